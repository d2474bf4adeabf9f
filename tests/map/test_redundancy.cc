// Keyframe redundancy: the incremental count equals the scan at every step.
#include <gtest/gtest.h>

#include <random>
#include <thread>

#include "core/map/atlas.h"
#include "core/map/redundancy.h"

namespace orbatlas {
namespace {

KeyFrameData keyframe_data(const std::vector<int>& levels) {
  KeyFrameData data;
  data.features.keypoints.resize(levels.size());
  for (std::size_t i = 0; i < levels.size(); ++i) data.features.keypoints[i].level = levels[i];
  return data;
}

KeyFrameData random_keyframe_data(std::size_t slots, std::mt19937& rng) {
  std::vector<int> levels(slots);
  for (auto& l : levels) l = std::uniform_int_distribution<int>(0, 7)(rng);
  return keyframe_data(levels);
}

// Checks both counts for every keyframe of the map; returns how many were compared.
int expect_counts_agree(const Map& map) {
  int n = 0;
  for (const auto& kf : map.keyframes()) {
    const RedundancyCount scan = count_redundant_scan(*kf);
    const RedundancyCount inc = count_redundant_incremental(*kf);
    EXPECT_EQ(inc.redundant, scan.redundant) << "keyframe " << kf->id();
    EXPECT_EQ(inc.map_points, scan.map_points) << "keyframe " << kf->id();
    ++n;
  }
  return n;
}

TEST(Redundancy, HandBuiltCase) {
  Atlas atlas;
  auto map = atlas.create_map();
  // Slot s of every keyframe is (or would be) an observation of point p_s.
  auto k = map->new_keyframe(keyframe_data({0, 2, 1, 0}));
  auto o1 = map->new_keyframe(keyframe_data({0, 3, 2, 0}));
  auto o2 = map->new_keyframe(keyframe_data({1, 3, 2, 0}));
  auto o3 = map->new_keyframe(keyframe_data({2, 0, 2, 0}));
  auto o4 = map->new_keyframe(keyframe_data({0, 3, 5, 0}));
  std::vector<std::shared_ptr<MapPoint>> p;
  for (int i = 0; i < 4; ++i) p.push_back(map->new_map_point({}));
  for (std::size_t s = 0; s < 4; ++s) {
    ASSERT_TRUE(k->add_observation(s, p[s]));
    ASSERT_TRUE(o1->add_observation(s, p[s]));
    ASSERT_TRUE(o2->add_observation(s, p[s]));
  }
  for (std::size_t s = 0; s < 3; ++s) ASSERT_TRUE(o3->add_observation(s, p[s]));
  ASSERT_TRUE(o4->add_observation(2, p[2]));
  // k: p0 (level 0) has o1 (0), o2 (1) at <= 1 but o3 (2) is coarser: 2 -> no.
  //    p1 (level 2): o1 3, o2 3, o3 0 all <= 3 -> yes.  p2 (level 1): o1, o2, o3 at 2 <= 2 -> yes (o4 at 5 not).
  //    p3: only o1, o2 -> no.
  const RedundancyCount expect_k{2, 4};
  for (const auto& c : {count_redundant_scan(*k), count_redundant_incremental(*k)}) {
    EXPECT_EQ(c.redundant, expect_k.redundant);
    EXPECT_EQ(c.map_points, expect_k.map_points);
  }
  EXPECT_FALSE(is_redundant(count_redundant_scan(*k)));                         // 2 > 0.9 * 4 fails
  EXPECT_TRUE(is_redundant(count_redundant_scan(*k), RedundancyOptions{0.4}));  // 2 > 1.6
  EXPECT_EQ(o1->redundant_map_point_count(), 2);                                // p1, p2
  EXPECT_EQ(o2->redundant_map_point_count(), 3);                                // p0 (k 0, o1 0, o3 2 <= 2), p1, p2
  EXPECT_EQ(o3->redundant_map_point_count(), 2);  // p0, p2; not p1 (seen at level 0, the others at >= 2)
  expect_counts_agree(*map);

  // o3 leaves p1: p1 is no longer redundant for k, o1 nor o2 (two others each).
  ASSERT_EQ(o3->erase_slot(1), p[1]);
  EXPECT_EQ(k->redundant_map_point_count(), 1);
  EXPECT_EQ(o1->redundant_map_point_count(), 1);
  EXPECT_EQ(o2->redundant_map_point_count(), 2);
  expect_counts_agree(*map);
  // o4 joins p1 at level 3: redundant again for k (2), o1 (3) and o2 (3) at once.
  ASSERT_TRUE(o4->add_observation(1, p[1]));
  EXPECT_EQ(k->redundant_map_point_count(), 2);
  EXPECT_EQ(o1->redundant_map_point_count(), 2);
  EXPECT_EQ(o2->redundant_map_point_count(), 3);
  expect_counts_agree(*map);
  // Culling o2 removes it from every point at once.
  ASSERT_TRUE(map->cull_keyframe(o2->id()));
  // k keeps two finer-or-equal others at most: p0 o1; p1 o1, o4; p2 o1, o3 (o4 at 5 is coarser).
  EXPECT_EQ(k->redundant_map_point_count(), 0);
  EXPECT_EQ(o1->redundant_map_point_count(), 0);  // likewise: p1 k, o4; p2 k, o3
  expect_counts_agree(*map);
}

struct RandomOps {
  std::shared_ptr<Map> map;
  std::vector<std::shared_ptr<KeyFrame>> kfs;
  std::vector<std::shared_ptr<MapPoint>> mps;
};

// One random edit on keyframe `kf`: add, erase or replace an observation.
void random_edit(KeyFrame& kf, const std::vector<std::shared_ptr<MapPoint>>& mps, std::mt19937& rng) {
  const std::size_t slot = rng() % kf.slot_count();
  const auto current = kf.map_point(slot);
  const int op = static_cast<int>(rng() % 10);
  if (current && op < 4) {
    kf.erase_slot(slot);
    return;
  }
  for (int attempt = 0; attempt < 5; ++attempt) {
    const auto& mp = mps[rng() % mps.size()];
    if (mp->slot_in(kf.id())) continue;
    if (current) {
      kf.replace(slot, mp);
    } else {
      kf.add_observation(slot, mp);
    }
    return;
  }
}

TEST(Redundancy, IncrementalEqualsScanUnderRandomEdits) {
  std::mt19937 rng(31337);
  Atlas atlas;
  RandomOps r;
  r.map = atlas.create_map();
  for (int i = 0; i < 25; ++i) r.kfs.push_back(r.map->new_keyframe(random_keyframe_data(60, rng)));
  for (int i = 0; i < 80; ++i) r.mps.push_back(r.map->new_map_point({}));
  int checked = 0, culls = 0;
  for (int batch = 0; batch < 80; ++batch) {
    for (int op = 0; op < 100; ++op) random_edit(*r.kfs[rng() % r.kfs.size()], r.mps, rng);
    // Now and then cull (and replace) a point or a keyframe.
    if (batch % 7 == 3) {
      const std::size_t i = rng() % r.mps.size();
      ASSERT_TRUE(r.map->cull_map_point(r.mps[i]->id()));
      r.mps[i] = r.map->new_map_point({});
      ++culls;
    }
    if (batch % 11 == 5) {
      const std::size_t i = rng() % r.kfs.size();
      ASSERT_TRUE(r.map->cull_keyframe(r.kfs[i]->id()));
      r.kfs[i] = r.map->new_keyframe(random_keyframe_data(60, rng));
      ++culls;
    }
    checked += expect_counts_agree(*r.map);
  }
  EXPECT_EQ(checked, 80 * 25);
  EXPECT_GT(culls, 10);
  // The random map did exercise redundant points.
  int redundant = 0;
  for (const auto& kf : r.kfs) redundant += kf->redundant_map_point_count();
  EXPECT_GT(redundant, 0);
}

TEST(Redundancy, IncrementalEqualsScanAfterConcurrentEdits) {
  std::mt19937 rng(5);
  Atlas atlas;
  RandomOps r;
  r.map = atlas.create_map();
  const int threads = 4, kf_per_thread = 6;
  for (int i = 0; i < threads * kf_per_thread; ++i) r.kfs.push_back(r.map->new_keyframe(random_keyframe_data(50, rng)));
  for (int i = 0; i < 60; ++i) r.mps.push_back(r.map->new_map_point({}));
  std::vector<std::thread> workers;
  for (int t = 0; t < threads; ++t) {
    // Each thread edits its own keyframes; the map points are shared by all.
    workers.emplace_back([&r, t] {
      std::mt19937 local(static_cast<unsigned>(100 + t));
      for (int op = 0; op < 3000; ++op) {
        const std::size_t k = static_cast<std::size_t>(t * kf_per_thread) + local() % kf_per_thread;
        random_edit(*r.kfs[k], r.mps, local);
        if (op % 200 == 0) r.kfs[k]->update_connections();
      }
    });
  }
  // A reader scanning meanwhile.
  workers.emplace_back([&r] {
    long sink = 0;
    for (int round = 0; round < 50; ++round)
      for (const auto& kf : r.map->keyframes())
        sink += count_redundant_scan(*kf).redundant + kf->redundant_map_point_count();
    EXPECT_GE(sink, 0);
  });
  for (auto& w : workers) w.join();
  EXPECT_EQ(expect_counts_agree(*r.map), threads * kf_per_thread);
}

TEST(Redundancy, BenchmarkCullingDecision) {
  std::mt19937 rng(1);
  Atlas atlas;
  auto map = atlas.create_map();
  const int n_kf = 300, n_mp = 6000, slots = 400, obs = 200;
  std::vector<std::shared_ptr<MapPoint>> mps;
  for (int i = 0; i < n_mp; ++i) mps.push_back(map->new_map_point({}));
  for (int k = 0; k < n_kf; ++k) {
    auto kf = map->new_keyframe(random_keyframe_data(slots, rng));
    const int base = k * (n_mp - obs) / (n_kf - 1);  // a sliding window: ~10 observers per point
    for (int p = 0; p < obs; ++p)
      kf->add_observation(static_cast<std::size_t>(p), mps[static_cast<std::size_t>(base + p)]);
  }
  const auto kfs = map->keyframes();
  const int repeats = 5;
  long redundant_scan = 0, redundant_incremental = 0;
  for (int r = 0; r < repeats; ++r)
    for (const auto& kf : kfs) redundant_scan += is_redundant(count_redundant_scan(*kf));
  for (int r = 0; r < repeats; ++r)
    for (const auto& kf : kfs) redundant_incremental += is_redundant(count_redundant_incremental(*kf));
  // Both schemes must take the same decisions; what each costs is measured by
  // `orbatlas run --compare-culling` (docs/benchmarks.md), not here.
  EXPECT_EQ(redundant_scan, redundant_incremental);
  EXPECT_GT(redundant_scan, 0) << "the benchmark map should contain redundant keyframes";
}

}  // namespace
}  // namespace orbatlas
