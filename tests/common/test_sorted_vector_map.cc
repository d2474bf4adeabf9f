// SortedVectorMap against std::map under the same random inserts, finds and
// erases: the same entries, in the same (key) order, after every step.
#include <gtest/gtest.h>

#include <map>
#include <random>

#include "core/common/sorted_vector_map.h"

namespace orbatlas {
namespace {

TEST(SortedVectorMap, AgreesWithStdMapUnderRandomInsertsAndErases) {
  SortedVectorMap<int, long> map;
  std::map<int, long> truth;
  std::mt19937 rng(7);
  for (int step = 0; step < 5000; ++step) {
    const int key = static_cast<int>(rng() % 64);  // few keys: many repeats and misses
    if (rng() % 3 != 0) {
      const long value = 1000L * step + key;
      const auto [it, inserted] = map.emplace(key, value);
      const auto [truth_it, truth_inserted] = truth.emplace(key, value);
      ASSERT_EQ(inserted, truth_inserted) << "key " << key;
      EXPECT_EQ(it->first, key);
      EXPECT_EQ(it->second, truth_it->second);  // an existing entry keeps its value
    } else {
      const auto it = map.find(key);
      ASSERT_EQ(it != map.end(), truth.contains(key)) << "key " << key;
      EXPECT_EQ(map.contains(key), truth.contains(key));
      if (it != map.end()) {
        map.erase(it);
        truth.erase(key);
      }
    }
    ASSERT_EQ(map.size(), truth.size());
    ASSERT_EQ(map.empty(), truth.empty());
    auto t = truth.begin();
    for (const auto& [k, v] : map) {
      ASSERT_EQ(k, t->first);
      ASSERT_EQ(v, t->second);
      ++t;
    }
  }
  const SortedVectorMap<int, long>& read_only = map;
  for (int key = 0; key < 64; ++key) EXPECT_EQ(read_only.find(key) != read_only.end(), truth.contains(key));
}

}  // namespace
}  // namespace orbatlas
