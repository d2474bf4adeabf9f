// FlatIdSet against std::set on the same ids: consecutive, spread over the
// whole 64-bit range, repeated, across growth and across passes (clear).
#include <gtest/gtest.h>

#include <random>
#include <set>

#include "core/common/flat_id_set.h"

namespace orbatlas {
namespace {

TEST(FlatIdSet, HoldsExactlyTheIdsInsertedAcrossGrowthAndPasses) {
  FlatIdSet set;
  EXPECT_FALSE(set.contains(7));  // never cleared: empty
  std::mt19937_64 rng(42);
  for (int pass = 0; pass < 3; ++pass) {
    set.clear(pass == 0 ? 0 : 1000);  // no room reserved first: it grows
    std::set<std::uint64_t> truth;
    for (int i = 0; i < 20000; ++i) {
      // Consecutive ids (as the allocators hand them out), repeats, and any 64-bit value.
      const std::uint64_t id = i % 3 == 0   ? static_cast<std::uint64_t>(i / 2)
                               : i % 3 == 1 ? (std::uint64_t{1} << 40) + static_cast<std::uint64_t>(i % 500)
                                            : rng() % (FlatIdSet::kEmpty - 1);
      EXPECT_EQ(set.insert(id), truth.insert(id).second) << "id " << id << ", pass " << pass;
    }
    EXPECT_EQ(set.size(), truth.size());
    for (const std::uint64_t id : truth) ASSERT_TRUE(set.contains(id));
    EXPECT_FALSE(set.contains(FlatIdSet::kEmpty - 1));
  }
  set.clear();
  EXPECT_EQ(set.size(), 0u);
  EXPECT_FALSE(set.contains(0));
  EXPECT_TRUE(set.insert(0));
  EXPECT_FALSE(set.insert(0));
}

}  // namespace
}  // namespace orbatlas
