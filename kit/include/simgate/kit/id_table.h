// simgate/kit/id_table.h — a connection's pending requests, by the id its client gave them.
//
// Ids are scoped to the connection (design.md, section 4): a transport keeps, for each of
// its clients, the ids of the requests not yet answered, to refuse a second request under
// an id still pending and to find the request a cancel names. The table sees an insert
// and an erase for every request, so it is a flat hash table: one vector of slots, linear
// probing, at most half full, and backward-shift deletion (no tombstones). Beside the slots,
// a dense array of one-byte tags (0: free; else seven bits of the hash) is what probing
// reads: an entry is touched only where its tag matches. A warm table
// allocates nothing: a slot's key keeps its buffer (ids longer than the small-string
// buffer, 15 bytes here, included) when its entry is erased or moved.
//
//   IdTable ids;
//   if (IdTable::Entry* e = ids.insert(client_id)) e->id = request;   // else: already pending
//   if (const IdTable::Entry* e = ids.find(client_id)) cancel(e->id);
//   const IdTable::Entry* e = ids.find(hash, request);   // the reply: no key hashed or compared
//   write(e->key, ...);  ids.erase(e);
//
// An entry pointer is valid until the table next changes (an insert may grow it, an erase
// may move entries): use it at once. Not thread-safe.
#ifndef SIMGATE_KIT_ID_TABLE_H_
#define SIMGATE_KIT_ID_TABLE_H_

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "simgate/kit/recycling_map.h"  // TransparentStringHash
#include "simgate/core/status.h"
#include "simgate/core/text.h"  // assign_text

namespace simgate::kit {

class IdTable {
 public:
  // One pending request.
  struct Entry {
    std::string key;       // the client's id (a free slot keeps its buffer)
    std::size_t hash = 0;  // of key
    RequestId id = 0;      // the request
  };

  // Adds `key` unless it is present: the new entry, whose id (0) the caller sets at once,
  // or null when `key` is already in the table.
  Entry* insert(std::string_view key) {
    if ((size_ + 1) * 2 > slots_.size()) grow();
    const std::size_t hash = hash_(key);
    const std::uint8_t t = tag(hash);
    std::size_t i = hash & mask();
    for (; tags_[i] != 0; i = (i + 1) & mask())
      if (tags_[i] == t && slots_[i].hash == hash && slots_[i].key == key) return nullptr;
    tags_[i] = t;
    Entry& e = slots_[i];
    assign_text(e.key, key);  // (`key` is never a slot's own)
    e.hash = hash;
    e.id = 0;
    ++size_;
    return &e;
  }

  // The entry of `key`, or null.
  const Entry* find(std::string_view key) const {
    if (size_ == 0) return nullptr;
    const std::size_t hash = hash_(key);
    const std::uint8_t t = tag(hash);
    for (std::size_t i = hash & mask(); tags_[i] != 0; i = (i + 1) & mask())
      if (tags_[i] == t && slots_[i].hash == hash && slots_[i].key == key) return &slots_[i];
    return nullptr;
  }

  // The entry of request `id`, whose key hashes to `hash` (as Entry::hash said): found
  // without hashing or comparing the key again. Null if there is none.
  const Entry* find(std::size_t hash, RequestId id) const {
    if (size_ == 0) return nullptr;
    const std::uint8_t t = tag(hash);
    for (std::size_t i = hash & mask(); tags_[i] != 0; i = (i + 1) & mask())
      if (tags_[i] == t && slots_[i].id == id && slots_[i].hash == hash) return &slots_[i];
    return nullptr;
  }

  // Removes `key`; false if it was not there.
  bool erase(std::string_view key) {
    const Entry* e = find(key);
    if (!e) return false;
    erase(e);
    return true;
  }

  // Removes an entry that find() or insert() returned (and nothing changed since).
  void erase(const Entry* entry) {
    std::size_t hole = static_cast<std::size_t>(entry - slots_.data());
    // backward shift: move up every later entry of the run that may sit at the hole (one
    // whose home slot is not cyclically between the hole and its own slot)
    for (std::size_t i = (hole + 1) & mask(); tags_[i] != 0; i = (i + 1) & mask()) {
      const std::size_t home = slots_[i].hash & mask();
      if (((i - home) & mask()) < ((i - hole) & mask())) continue;
      move_entry(hole, i);
      hole = i;
    }
    tags_[hole] = 0;  // its key keeps its buffer for a later insert
    --size_;
  }

  // Calls f(const Entry&) for every entry, in no particular order.
  template <class F>
  void for_each(F&& f) const {
    for (std::size_t i = 0; i < tags_.size(); ++i)
      if (tags_[i] != 0) f(slots_[i]);
  }

  void clear() {
    std::fill(tags_.begin(), tags_.end(), std::uint8_t{0});
    size_ = 0;
  }

  std::size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }

 private:
  static constexpr std::size_t k_first_capacity = 16;

  std::size_t mask() const { return slots_.size() - 1; }

  // A used slot's tag: seven bits of the hash that do not pick the slot (its top ones),
  // never 0 (a free slot's).
  static std::uint8_t tag(std::size_t hash) {
    return static_cast<std::uint8_t>(hash >> (8 * sizeof(std::size_t) - 8)) | 1u;
  }

  // Moves slot `from`'s entry into the free slot `to`; `from` keeps `to`'s spare key buffer.
  void move_entry(std::size_t to, std::size_t from) {
    slots_[to].key.swap(slots_[from].key);
    slots_[to].hash = slots_[from].hash;
    slots_[to].id = slots_[from].id;
    tags_[to] = tags_[from];
  }

  // Doubles the capacity (16 at first) and places every entry again.
  void grow() {
    const std::size_t capacity = slots_.empty() ? k_first_capacity : slots_.size() * 2;
    std::vector<Entry> old(capacity);
    std::vector<std::uint8_t> old_tags(capacity, 0);
    old.swap(slots_);
    old_tags.swap(tags_);
    for (std::size_t j = 0; j < old.size(); ++j) {
      if (old_tags[j] == 0) continue;
      std::size_t i = old[j].hash & mask();
      while (tags_[i] != 0) i = (i + 1) & mask();
      slots_[i].key.swap(old[j].key);
      slots_[i].hash = old[j].hash;
      slots_[i].id = old[j].id;
      tags_[i] = old_tags[j];
    }
  }

  // Probing reads the tags, one byte a slot in a dense array (a table of 256 slots in four
  // cache lines), and an entry only where its tag matches: 1 in 128 of the others.
  std::vector<std::uint8_t> tags_;  // per slot: 0 if free, else tag(hash)
  std::vector<Entry> slots_;        // as many as tags_: a power of two, or none
  std::size_t size_ = 0;            // entries
  TransparentStringHash hash_;
};

}  // namespace simgate::kit

#endif  // SIMGATE_KIT_ID_TABLE_H_
