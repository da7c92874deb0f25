// simgate/kit/request_slots.h — a transport's table of the requests it sent to the core,
// addressed by RequestIds that name their own slot.
//
// A transport remembers, for each request it submits, where the reply goes. With ids from
// new_request_id() that table is a hash map: a hash, a bucket walk and a node per request.
// RequestSlots allocates the ids itself instead: an id carries the index of its slot in a
// vector, so insert, find and erase are an index and a compare.
//
//   RequestSlots<Pending> requests;
//   RequestId id = requests.insert({session, client_id});   // then submit(id, call)
//   ...
//   if (Pending* p = requests.find(id)) { reply(*p); requests.erase(id); }
//
// An id is  1 (bit 63) | generation (39 bits) | slot index (24 bits):
//   - bit 63 keeps these ids apart from new_request_id()'s (a counter from 1), so a
//     transport may use both with one manager;
//   - the generation changes each time a slot is freed: the id of an erased entry (an
//     outcome arriving after its client left) never finds the slot's next entry, until
//     that one slot has been reused 2^39 times;
//   - at most 2^24 (16 777 216) entries live at once; insert() throws std::length_error
//     past that.
// The core needs ids to be unique only within one manager (RequestId, status.h).
//
// Freed slots are reused last-freed-first; the vector keeps the size of the largest number
// of entries live at once. An erased value is reset to T{} (so a kept slot holds no
// reference to anything). Not thread-safe.
#ifndef SIMGATE_KIT_REQUEST_SLOTS_H_
#define SIMGATE_KIT_REQUEST_SLOTS_H_

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <utility>
#include <vector>

#include "simgate/core/status.h"

namespace simgate::kit {

template <class T>
class RequestSlots {
 public:
  static constexpr int k_index_bits = 24;
  static constexpr int k_generation_bits = 39;
  static constexpr std::size_t k_max_live = std::size_t{1} << k_index_bits;
  static constexpr RequestId k_mark = RequestId{1} << 63;  // set in every id of this table

  // Stores `value` in a free slot; returns its id. Throws std::length_error when
  // k_max_live entries are live.
  RequestId insert(T value) {
    std::uint32_t index;
    if (!free_.empty()) {
      index = free_.back();
      free_.pop_back();
    } else {
      if (slots_.size() >= k_max_live)
        throw std::length_error("more than 16777216 requests waiting for their outcome");
      index = static_cast<std::uint32_t>(slots_.size());
      slots_.emplace_back();
    }
    Slot& slot = slots_[index];
    slot.live = true;
    slot.value = std::move(value);
    return id_of(slot.generation, index);
  }

  // The entry of `id`, or null (erased, or never one of this table's ids).
  T* find(RequestId id) {
    const std::size_t index = id & (k_max_live - 1);
    if (index >= slots_.size()) return nullptr;
    Slot& slot = slots_[index];
    if (!slot.live || id != id_of(slot.generation, index)) return nullptr;
    return &slot.value;
  }

  // Whether `id` names a live entry (find() without the entry).
  bool contains(RequestId id) const {
    const std::size_t index = id & (k_max_live - 1);
    return index < slots_.size() && slots_[index].live &&
           id == id_of(slots_[index].generation, index);
  }

  // Frees the slot of `id`; false if there was no such entry.
  bool erase(RequestId id) {
    if (!find(id)) return false;
    free_slot(static_cast<std::uint32_t>(id & (k_max_live - 1)));
    return true;
  }

  // Erases every entry (the slots and their generations stay: old ids still find nothing).
  void clear() {
    for (std::size_t i = 0; i < slots_.size(); ++i)
      if (slots_[i].live) free_slot(static_cast<std::uint32_t>(i));
  }

  std::size_t size() const { return slots_.size() - free_.size(); }
  bool empty() const { return size() == 0; }

 private:
  struct Slot {
    std::uint64_t generation = 0;  // part of the id of the slot's current entry
    bool live = false;             // the slot holds an entry
    T value{};                     // the entry (T{} when free)
  };

  static RequestId id_of(std::uint64_t generation, std::uint32_t index) {
    return k_mark | (generation << k_index_bits) | index;
  }

  // Resets a live slot's value, moves it to its next generation and lists it as free.
  void free_slot(std::uint32_t index) {
    Slot& slot = slots_[index];
    slot.live = false;
    slot.value = T{};
    slot.generation = (slot.generation + 1) & ((std::uint64_t{1} << k_generation_bits) - 1);
    free_.push_back(index);
  }

  std::vector<Slot> slots_;          // indexed by the low bits of an id
  std::vector<std::uint32_t> free_;  // indexes of free slots, reused last-freed-first
};

}  // namespace simgate::kit

#endif  // SIMGATE_KIT_REQUEST_SLOTS_H_
