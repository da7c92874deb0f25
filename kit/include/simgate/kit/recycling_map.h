// simgate/kit/recycling_map.h — an unordered_map that keeps the nodes of erased entries.
//
// A transport's request table sees one insert and one erase per request. With a plain
// std::unordered_map each of them is a malloc and a free; RecyclingMap extracts erased
// nodes (C++17 node handles) into a bounded free list and reuses them for the next
// inserts, so a warm table allocates nothing. A node keeps its key's and value's capacity
// (a std::string key reuses its buffer).
//
//   RecyclingMap<RequestId, Pending> requests;
//   requests.emplace(id, Pending{...});
//   auto it = requests.find(id);  ...  requests.erase(it);
//
// An erased value is reset to T{}, so a kept node holds no reference to anything. A T with
// a member `void recycle()` is reset by it instead, to keep what is worth keeping (a
// string's capacity) while dropping references; try_emplace(key) without value arguments
// then hands that value back for the caller to fill:
//
//   struct Pending {
//     std::weak_ptr<Session> to;
//     std::string method;
//     void recycle() { to.reset(); }
//   };
//   Pending& p = table.try_emplace(id).first->second;  p.to = ...;  p.method.assign(...);
//
// An entry that must outlive changes to the table while it is used (a reply may close its
// connection, which erases entries) is taken out with extract() and given back with
// recycle().
//
// Not thread-safe (like the map it wraps). Heterogeneous lookup works when Hash and Eq
// are transparent (see TransparentStringHash).
#ifndef SIMGATE_KIT_RECYCLING_MAP_H_
#define SIMGATE_KIT_RECYCLING_MAP_H_

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <functional>
#include <string>
#include <string_view>
#include <unordered_map>
#include <utility>
#include <vector>

namespace simgate::kit {

// Lets an unordered_map<std::string, ...> be searched with a std::string_view (no
// temporary string). Not noexcept on purpose: libstdc++ then stores each node's hash code
// (as it does for std::hash<std::string>), so erasing a node or walking a bucket never
// hashes a key again.
//
// Request ids are short: up to 16 bytes are hashed inline (two overlapping loads and one
// 64x64->128-bit multiply, about 20 instructions); longer keys use std::hash. Like
// std::hash, it is not seeded: a client can make its own ids collide, which costs only its
// own connection's table (bounded by max_in_flight).
struct TransparentStringHash {
  using is_transparent = void;
  std::size_t operator()(std::string_view s) const {
    const std::size_t n = s.size();
    if (n > 16) return std::hash<std::string_view>{}(s);
    const char* p = s.data();
    std::uint64_t a = 0, b = 0;
    if (n >= 8) {
      std::memcpy(&a, p, 8);
      std::memcpy(&b, p + n - 8, 8);
    } else if (n >= 4) {
      std::uint32_t x, y;
      std::memcpy(&x, p, 4);
      std::memcpy(&y, p + n - 4, 4);
      a = x;
      b = y;
    } else if (n > 0) {
      a = std::uint64_t(static_cast<unsigned char>(p[0])) |
          std::uint64_t(static_cast<unsigned char>(p[n / 2])) << 8 |
          std::uint64_t(static_cast<unsigned char>(p[n - 1])) << 16;
    }
    __extension__ using U128 = unsigned __int128;  // GCC and Clang on 64-bit targets
    const U128 m = static_cast<U128>(a ^ 0x9E3779B97F4A7C15ull) * (b ^ 0xC2B2AE3D27D4EB4Full ^ n);
    return static_cast<std::size_t>(static_cast<std::uint64_t>(m) ^
                                    static_cast<std::uint64_t>(m >> 64));
  }
};

template <class Key, class T, class Hash = std::hash<Key>, class Eq = std::equal_to<>>
class RecyclingMap {
  using Map = std::unordered_map<Key, T, Hash, Eq>;

 public:
  using iterator = typename Map::iterator;
  using const_iterator = typename Map::const_iterator;

  // At most `max_free` erased nodes are kept (the memory a burst leaves behind is bounded).
  explicit RecyclingMap(std::size_t max_free = 1024) : max_free_(max_free) {}

  using node_type = typename Map::node_type;

  // Inserts key -> T(args...) unless the key is present (like try_emplace). Without value
  // arguments a kept node's value is left as its reset made it.
  template <class K, class... Args>
  std::pair<iterator, bool> try_emplace(K&& key, Args&&... args) {
    if (free_.empty())
      return map_.try_emplace(Key(std::forward<K>(key)), std::forward<Args>(args)...);
    auto node = std::move(free_.back());
    free_.pop_back();
    node.key() = std::forward<K>(key);
    if constexpr (sizeof...(Args) > 0) node.mapped() = T(std::forward<Args>(args)...);
    auto result = map_.insert(std::move(node));
    if (!result.inserted) keep(std::move(result.node));
    return {result.position, result.inserted};
  }

  template <class K>
  iterator find(const K& key) {
    return map_.find(key);
  }
  template <class K>
  const_iterator find(const K& key) const {
    return map_.find(key);
  }

  void erase(iterator it) {
    if (free_.size() < max_free_)
      keep(map_.extract(it));
    else
      map_.erase(it);
  }
  template <class K>
  bool erase_key(const K& key) {
    auto it = map_.find(key);
    if (it == map_.end()) return false;
    erase(it);
    return true;
  }
  // Takes an entry out of the table; give its node back with recycle() when done with it.
  node_type extract(iterator it) { return map_.extract(it); }
  void recycle(node_type node) { keep(std::move(node)); }
  void clear() { map_.clear(); }

  iterator begin() { return map_.begin(); }
  iterator end() { return map_.end(); }
  const_iterator begin() const { return map_.begin(); }
  const_iterator end() const { return map_.end(); }
  std::size_t size() const { return map_.size(); }
  bool empty() const { return map_.empty(); }

 private:
  // the value is reset (see the top of this file); the key keeps its capacity
  void keep(node_type node) {
    if (node.empty() || free_.size() >= max_free_) return;
    if constexpr (requires(T& value) { value.recycle(); })
      node.mapped().recycle();
    else
      node.mapped() = T{};
    free_.push_back(std::move(node));
  }

  Map map_;                      // the live entries
  std::vector<node_type> free_;  // erased nodes, reused by the next inserts
  std::size_t max_free_;         // bound on free_
};

}  // namespace simgate::kit

#endif  // SIMGATE_KIT_RECYCLING_MAP_H_
