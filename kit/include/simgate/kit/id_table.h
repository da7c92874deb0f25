// simgate/kit/id_table.h — a connection's pending requests, by the id its client gave them.
//
// Ids are scoped to the connection (design.md, section 4): a transport keeps, for each of
// its clients, the ids of the requests not yet answered, to refuse a second request under
// an id still pending and to find the request a cancel names. The table sees an insert
// and an erase for every request, so it is a flat hash table: one vector of slots, linear
// probing, at most half full, and backward-shift deletion (no tombstones). A warm table
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

#include <cstddef>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "simgate/kit/recycling_map.h"  // TransparentStringHash
#include "simgate/core/status.h"

namespace simgate::kit {

class IdTable {
 public:
  // One pending request. `used` is false in a free slot.
  struct Entry {
    std::string key;       // the client's id (a free slot keeps its buffer)
    std::size_t hash = 0;  // of key
    RequestId id = 0;      // the request
    bool used = false;     // the slot holds an entry
  };

  // Adds `key` unless it is present: the new entry, whose id (0) the caller sets at once,
  // or null when `key` is already in the table.
  Entry* insert(std::string_view key) {
    if ((size_ + 1) * 2 > slots_.size()) grow();
    const std::size_t hash = hash_(key);
    std::size_t i = hash & mask();
    for (; slots_[i].used; i = (i + 1) & mask())
      if (slots_[i].hash == hash && slots_[i].key == key) return nullptr;
    Entry& e = slots_[i];
    e.key.assign(key);
    e.hash = hash;
    e.id = 0;
    e.used = true;
    ++size_;
    return &e;
  }

  // The entry of `key`, or null.
  const Entry* find(std::string_view key) const {
    if (size_ == 0) return nullptr;
    const std::size_t hash = hash_(key);
    for (std::size_t i = hash & mask(); slots_[i].used; i = (i + 1) & mask())
      if (slots_[i].hash == hash && slots_[i].key == key) return &slots_[i];
    return nullptr;
  }

  // The entry of request `id`, whose key hashes to `hash` (as Entry::hash said): found
  // without hashing or comparing the key again. Null if there is none.
  const Entry* find(std::size_t hash, RequestId id) const {
    if (size_ == 0) return nullptr;
    for (std::size_t i = hash & mask(); slots_[i].used; i = (i + 1) & mask())
      if (slots_[i].id == id && slots_[i].hash == hash) return &slots_[i];
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
    for (std::size_t i = (hole + 1) & mask(); slots_[i].used; i = (i + 1) & mask()) {
      const std::size_t home = slots_[i].hash & mask();
      if (((i - home) & mask()) < ((i - hole) & mask())) continue;
      move_entry(slots_[hole], slots_[i]);
      hole = i;
    }
    slots_[hole].used = false;  // its key keeps its buffer for a later insert
    --size_;
  }

  // Calls f(const Entry&) for every entry, in no particular order.
  template <class F>
  void for_each(F&& f) const {
    for (const Entry& e : slots_)
      if (e.used) f(e);
  }

  void clear() {
    for (Entry& e : slots_) e.used = false;
    size_ = 0;
  }

  std::size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }

 private:
  static constexpr std::size_t k_first_capacity = 16;

  std::size_t mask() const { return slots_.size() - 1; }

  // Moves `from`'s entry into the free slot `to`; `from` keeps `to`'s spare key buffer.
  static void move_entry(Entry& to, Entry& from) {
    to.key.swap(from.key);
    to.hash = from.hash;
    to.id = from.id;
    to.used = true;
  }

  // Doubles the capacity (16 at first) and places every entry again.
  void grow() {
    std::vector<Entry> old(slots_.empty() ? k_first_capacity : slots_.size() * 2);
    old.swap(slots_);
    for (Entry& e : old) {
      if (!e.used) continue;
      std::size_t i = e.hash & mask();
      while (slots_[i].used) i = (i + 1) & mask();
      move_entry(slots_[i], e);
    }
  }

  std::vector<Entry> slots_;  // a power of two in size, or empty
  std::size_t size_ = 0;      // entries
  TransparentStringHash hash_;
};

}  // namespace simgate::kit

#endif  // SIMGATE_KIT_ID_TABLE_H_
