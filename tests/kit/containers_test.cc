// The hot-path helpers of the core: RecyclingMap (request tables that reuse their nodes),
// IdTable (a connection's pending requests by client id),
// TransparentStringHash (their string keys), RequestSlots (ids that name their slot) and
// BoundArguments (arguments held inline, or on the heap beyond 8 parameters).
#include <algorithm>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "simgate/kit/id_table.h"
#include "simgate/kit/recycling_map.h"
#include "simgate/kit/request_slots.h"

namespace simgate::kit {
namespace {

TEST(RecyclingMapTest, ErasedNodesAreReusedWithFreshValues) {
  RecyclingMap<std::string, std::shared_ptr<int>, TransparentStringHash> map;
  auto held = std::make_shared<int>(7);
  ASSERT_TRUE(
      map.try_emplace(std::string_view("a long client id, beyond any small-string buffer"), held)
          .second);
  EXPECT_EQ(held.use_count(), 2);
  const std::string* key_storage =
      &map.find(std::string_view("a long client id, beyond any small-string buffer"))->first;

  map.erase(map.find(std::string_view("a long client id, beyond any small-string buffer")));
  EXPECT_TRUE(map.empty());
  // the kept node holds no reference to the erased value
  EXPECT_EQ(held.use_count(), 1);

  // the next insert takes the kept node: same node, new key and value
  auto other = std::make_shared<int>(8);
  ASSERT_TRUE(map.try_emplace(std::string_view("b"), other).second);
  auto it = map.find(std::string_view("b"));
  ASSERT_NE(it, map.end());
  EXPECT_EQ(&it->first, key_storage);
  EXPECT_EQ(*it->second, 8);
  EXPECT_EQ(map.find(std::string_view("a long client id, beyond any small-string buffer")),
            map.end());
}

TEST(RecyclingMapTest, DuplicateKeysAreRefusedAndTheNodeIsKept) {
  RecyclingMap<int, std::string> map;
  map.try_emplace(1, "one");
  map.try_emplace(2, "two");
  EXPECT_TRUE(map.erase_key(2));
  EXPECT_FALSE(map.erase_key(2));
  auto [it, inserted] = map.try_emplace(1, "uno");  // takes the kept node, then gives it back
  EXPECT_FALSE(inserted);
  EXPECT_EQ(it->second, "one");
  EXPECT_TRUE(map.try_emplace(3, "three").second);
  EXPECT_EQ(map.size(), 2u);
  EXPECT_EQ(map.find(3)->second, "three");
}

TEST(RecyclingMapTest, TheFreeListIsBounded) {
  RecyclingMap<int, int> map(/*max_free=*/2);
  for (int i = 0; i < 100; ++i) map.try_emplace(i, i);
  for (int i = 0; i < 100; ++i) EXPECT_TRUE(map.erase_key(i));
  EXPECT_TRUE(map.empty());
  for (int i = 0; i < 100; ++i) map.try_emplace(i, -i);
  EXPECT_EQ(map.size(), 100u);
  for (int i = 0; i < 100; ++i) EXPECT_EQ(map.find(i)->second, -i);
}

struct KeepsCapacity {
  std::shared_ptr<int> ref;
  std::string text;
  void recycle() { ref.reset(); }
};

TEST(RecyclingMapTest, AValueWithRecycleKeepsWhatItChoosesAndExtractedNodesComeBack) {
  RecyclingMap<int, KeepsCapacity> map;
  auto held = std::make_shared<int>(1);
  auto& first = map.try_emplace(1).first->second;
  first.ref = held;
  first.text.assign(100, 'x');
  const char* buffer = first.text.data();

  // taken out while in use, then given back: recycle() dropped the reference only
  auto node = map.extract(map.find(1));
  EXPECT_TRUE(map.empty());
  EXPECT_EQ(node.mapped().ref, held);
  map.recycle(std::move(node));
  EXPECT_EQ(held.use_count(), 1);

  // without value arguments the kept value comes back as recycle() left it, to be filled
  auto& again = map.try_emplace(2).first->second;
  EXPECT_EQ(again.ref, nullptr);
  again.text.assign(50, 'y');
  EXPECT_EQ(again.text.data(), buffer);
}

TEST(TransparentStringHashTest, EqualTextEqualHashAndShortIdsSpreadOut) {
  TransparentStringHash hash;
  // std::string and string_view of the same text (heterogeneous lookup depends on it)
  for (std::string text : std::initializer_list<std::string>{
           "", "a", "ab", "abc", "abcd", "1234567", "12345678", "123456789abcdef0",
           "123456789abcdef01", std::string(100, 'x')})
    EXPECT_EQ(hash(text), hash(std::string_view(text))) << text;
  // the ids clients use (counters, prefixed counters, uuids' pieces): no two of these
  // 20 000 collide in 64 bits, and their low bits (which pick buckets) spread
  std::set<std::size_t> full, low;
  int count = 0;
  for (int i = 0; i < 10000; ++i) {
    for (const std::string& id : {std::to_string(i), "req" + std::to_string(i)}) {
      full.insert(hash(id));
      low.insert(hash(id) % 4093);
      ++count;
    }
  }
  EXPECT_EQ(full.size(), std::size_t(count));
  EXPECT_GT(low.size(), 4000u);  // 4 093 buckets, 20 000 keys: nearly every bucket used
  // same bytes, other length; the same 16 bytes at both ends of a longer key
  EXPECT_NE(hash(std::string_view("a\0", 2)), hash(std::string_view("a", 1)));
  EXPECT_NE(hash("abcdefghij"), hash("abcdefghijk"));
}

TEST(IdTableTest, InsertFindEraseAndDuplicatesAreRefused) {
  IdTable ids;
  EXPECT_TRUE(ids.empty());
  EXPECT_EQ(ids.find("a"), nullptr);
  EXPECT_FALSE(ids.erase("a"));
  IdTable::Entry* a = ids.insert("a");
  ASSERT_NE(a, nullptr);
  EXPECT_EQ(a->key, "a");
  EXPECT_EQ(a->id, RequestId{0});
  a->id = 7;
  EXPECT_EQ(ids.insert("a"), nullptr);  // already pending
  ASSERT_NE(ids.find("a"), nullptr);
  EXPECT_EQ(ids.find("a")->id, RequestId{7});
  EXPECT_EQ(ids.size(), 1u);
  const std::string long_id(100, 'x');  // beyond the small-string buffer
  IdTable::Entry* x = ids.insert(long_id);
  x->id = 8;
  const std::size_t x_hash = x->hash;
  EXPECT_EQ(ids.find(long_id)->id, RequestId{8});
  EXPECT_EQ(ids.find(std::string(99, 'x')), nullptr);
  // by the request: its hash and id, no key
  ASSERT_NE(ids.find(x_hash, 8), nullptr);
  EXPECT_EQ(ids.find(x_hash, 8)->key, long_id);
  EXPECT_EQ(ids.find(x_hash, 7), nullptr);
  EXPECT_TRUE(ids.erase("a"));
  EXPECT_EQ(ids.find("a"), nullptr);
  EXPECT_EQ(ids.find(long_id)->id, RequestId{8});
  ids.erase(ids.find(x_hash, 8));
  EXPECT_TRUE(ids.empty());
  ASSERT_NE(ids.insert("a"), nullptr);  // free again
  ids.clear();
  EXPECT_TRUE(ids.empty());
  EXPECT_EQ(ids.find(long_id), nullptr);
}

TEST(IdTableTest, AgreesWithAMapThroughRandomInsertsAndErases) {
  // growth and backward-shift deletion, checked against std::map after every operation
  // batch; few distinct keys, so that runs of colliding slots form and are erased from
  IdTable ids;
  std::map<std::string, RequestId> model;
  std::mt19937 random(12345);
  for (int step = 0; step < 20000; ++step) {
    const std::string key = std::to_string(random() % 300);
    if (random() % 3 != 0) {
      IdTable::Entry* entry = ids.insert(key);
      ASSERT_EQ(entry != nullptr, model.count(key) == 0) << key;
      if (entry) entry->id = model[key] = RequestId(step + 1);
    } else if (random() % 2 == 0) {
      ASSERT_EQ(ids.erase(key), model.erase(key) == 1) << key;
    } else if (auto it = model.find(key); it != model.end()) {
      // as a reply does: found by its hash and request id, erased by position
      const IdTable::Entry* entry = ids.find(ids.find(key)->hash, it->second);
      ASSERT_NE(entry, nullptr) << key;
      ASSERT_EQ(entry->key, key);
      ids.erase(entry);
      model.erase(it);
    }
    if (step % 97 != 0) continue;
    ASSERT_EQ(ids.size(), model.size());
    for (const auto& [k, id] : model) {
      const IdTable::Entry* found = ids.find(k);
      ASSERT_NE(found, nullptr) << k;
      ASSERT_EQ(found->id, id) << k;
    }
    std::size_t seen = 0;
    ids.for_each([&](const IdTable::Entry& e) {
      ++seen;
      EXPECT_EQ(model.at(e.key), e.id);
    });
    ASSERT_EQ(seen, model.size());
  }
}

// Keys whose hashes pick the same slot of a 16-slot table (the first capacity) and share
// the top byte the tags are made of: probing must compare the entries behind equal tags.
std::vector<std::string> keys_with_one_slot_and_tag(std::size_t count) {
  const TransparentStringHash hash;
  std::map<std::size_t, std::vector<std::string>> groups;  // by (home slot, tag byte)
  for (int i = 0;; ++i) {
    std::string key = "id" + std::to_string(i);
    const std::size_t h = hash(key);
    auto& group = groups[(h & 15) | ((h >> 56) | 1) << 8];
    group.push_back(std::move(key));
    if (group.size() == count) return group;
  }
}

TEST(IdTableTest, KeysWithTheSameSlotAndTagAreToldApart) {
  const std::vector<std::string> keys = keys_with_one_slot_and_tag(4);
  IdTable ids;
  std::size_t hash = 0;
  for (std::size_t k = 0; k < keys.size(); ++k) {
    IdTable::Entry* e = ids.insert(keys[k]);
    ASSERT_NE(e, nullptr) << keys[k];
    e->id = k + 1;
    hash = e->hash;
  }
  for (std::size_t k = 0; k < keys.size(); ++k) {
    EXPECT_EQ(ids.insert(keys[k]), nullptr);
    ASSERT_NE(ids.find(keys[k]), nullptr);
    EXPECT_EQ(ids.find(keys[k])->id, k + 1);
    // by hash and request id: the entry of that request, not the first of the same tag
    const IdTable::Entry* e = ids.find(ids.find(keys[k])->hash, k + 1);
    ASSERT_NE(e, nullptr);
    EXPECT_EQ(e->key, keys[k]);
  }
  EXPECT_EQ(ids.find(hash, 99), nullptr);
  EXPECT_EQ(ids.find("not there"), nullptr);
}

TEST(IdTableTest, EraseShiftsTheRunBackAndFreeSlotsKeepTheirBuffers) {
  // a run of four entries with one home slot: erasing its first moves the others up
  const std::vector<std::string> keys = keys_with_one_slot_and_tag(4);
  IdTable ids;
  const std::string long_key(100, 'L');  // beyond the small-string buffer
  IdTable::Entry* long_entry = ids.insert(long_key);
  long_entry->id = 50;
  for (std::size_t k = 0; k < keys.size(); ++k) ids.insert(keys[k])->id = k + 1;
  EXPECT_TRUE(ids.erase(keys[0]));
  EXPECT_EQ(ids.find(keys[0]), nullptr);
  for (std::size_t k = 1; k < keys.size(); ++k) {
    ASSERT_NE(ids.find(keys[k]), nullptr) << k;
    EXPECT_EQ(ids.find(keys[k])->id, k + 1);
  }
  EXPECT_EQ(ids.find(long_key)->id, RequestId{50});
  // from the middle of the run, by position as a reply does
  ids.erase(ids.find(ids.find(keys[2])->hash, 3));
  EXPECT_EQ(ids.find(keys[2]), nullptr);
  EXPECT_EQ(ids.find(keys[1])->id, RequestId{2});
  EXPECT_EQ(ids.find(keys[3])->id, RequestId{4});
  EXPECT_EQ(ids.size(), 3u);
  // the long key's slot, freed, keeps its buffer: a key inserted there reuses it
  const std::size_t long_hash = ids.find(long_key)->hash;
  ids.erase(ids.find(long_hash, 50));
  ids.erase(keys[1]);
  ids.erase(keys[3]);
  ASSERT_TRUE(ids.empty());
  std::string key;  // a short key whose home is that slot (the table still has 16)
  for (int i = 0; key.empty(); ++i)
    if ((TransparentStringHash{}("k" + std::to_string(i)) & 15) == (long_hash & 15))
      key = "k" + std::to_string(i);
  const std::size_t capacity = ids.insert(key)->key.capacity();
  EXPECT_GE(capacity, long_key.size());
}

TEST(IdTableTest, GrowthKeepsEveryEntry) {
  IdTable ids;
  std::vector<std::size_t> hashes;
  for (int i = 0; i < 1000; ++i) {
    IdTable::Entry* e = ids.insert("request-" + std::to_string(i));
    ASSERT_NE(e, nullptr);
    e->id = i + 1;
    hashes.push_back(e->hash);
  }
  EXPECT_EQ(ids.size(), 1000u);
  for (int i = 0; i < 1000; ++i) {
    const IdTable::Entry* e = ids.find(hashes[i], i + 1);
    ASSERT_NE(e, nullptr) << i;
    EXPECT_EQ(e->key, "request-" + std::to_string(i));
    EXPECT_EQ(ids.insert(e->key), nullptr);
  }
  for (int i = 0; i < 1000; i += 2) ids.erase(ids.find(hashes[i], i + 1));
  EXPECT_EQ(ids.size(), 500u);
  std::size_t seen = 0;
  ids.for_each([&](const IdTable::Entry& e) {
    ++seen;
    EXPECT_EQ(e.id % 2, 0u);
  });
  EXPECT_EQ(seen, 500u);
}

TEST(RequestSlotsTest, IdsFindTheirEntryUntilErasedAndNeverTheSlotsNextEntry) {
  RequestSlots<std::shared_ptr<int>> slots;
  auto value = std::make_shared<int>(1);
  const RequestId a = slots.insert(value);
  const RequestId b = slots.insert(std::make_shared<int>(2));
  EXPECT_NE(a, b);
  ASSERT_NE(slots.find(a), nullptr);
  EXPECT_EQ(**slots.find(a), 1);
  EXPECT_EQ(**slots.find(b), 2);
  EXPECT_EQ(slots.size(), 2u);

  // erased: the value is released, the id finds nothing, even once the slot is reused
  EXPECT_TRUE(slots.erase(a));
  EXPECT_EQ(value.use_count(), 1);
  EXPECT_EQ(slots.find(a), nullptr);
  EXPECT_FALSE(slots.erase(a));
  const RequestId c = slots.insert(std::make_shared<int>(3));
  EXPECT_NE(c, a);
  EXPECT_EQ((c ^ a) & (RequestSlots<int>::k_max_live - 1), 0u);  // a's slot, reused
  EXPECT_EQ(slots.find(a), nullptr);
  EXPECT_EQ(**slots.find(c), 3);
  EXPECT_EQ(slots.size(), 2u);

  // ids from new_request_id() (a counter from 1) are never this table's
  for (RequestId id : {RequestId{1}, RequestId{2}, RequestId{1000}})
    EXPECT_EQ(slots.find(id), nullptr);
  EXPECT_EQ(slots.find(0), nullptr);
  EXPECT_EQ(slots.find(RequestSlots<int>::k_mark | 12345), nullptr);  // a slot never used
  EXPECT_NE(c & RequestSlots<int>::k_mark, 0u);

  slots.clear();
  EXPECT_TRUE(slots.empty());
  EXPECT_EQ(slots.find(b), nullptr);
  EXPECT_EQ(slots.find(c), nullptr);
}

TEST(RequestSlotsTest, ManyLiveEntriesEachFindTheirOwn) {
  RequestSlots<int> slots;
  std::vector<RequestId> ids;
  for (int round = 0; round < 3; ++round) {
    ids.clear();
    for (int i = 0; i < 1000; ++i) ids.push_back(slots.insert(i));
    std::set<RequestId> distinct(ids.begin(), ids.end());
    EXPECT_EQ(distinct.size(), ids.size());
    for (int i = 0; i < 1000; ++i) ASSERT_EQ(*slots.find(ids[std::size_t(i)]), i);
    // out of order, as async outcomes come back
    for (std::size_t i = 0; i < ids.size(); i += 2) EXPECT_TRUE(slots.erase(ids[i]));
    for (std::size_t i = 1; i < ids.size(); i += 2) EXPECT_TRUE(slots.erase(ids[i]));
    EXPECT_TRUE(slots.empty());
  }
}

}  // namespace
}  // namespace simgate::kit
