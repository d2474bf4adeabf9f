// Culled keyframes and map points are freed as soon as nobody holds them, stay
// valid while some thread does, and never leak through the graph links.
#include <gtest/gtest.h>

#include <atomic>
#include <future>
#include <random>
#include <thread>
#include <unordered_set>

#include "core/common/error.h"
#include "core/map/atlas.h"
#include "core/map/redundancy.h"

namespace orbatlas {
namespace {

KeyFrameData keyframe_data(std::size_t slots, std::mt19937* rng = nullptr) {
  KeyFrameData data;
  data.timestamp_ns = 1'000'000'007;
  data.T_w_b.t = Eigen::Vector3d(1, 2, 3);
  data.features.keypoints.resize(slots);
  data.features.descriptors.resize(slots);
  for (std::size_t i = 0; i < slots; ++i) {
    data.features.keypoints[i].level = rng ? std::uniform_int_distribution<int>(0, 7)(*rng) : 0;
    data.features.descriptors[i] = {i, i + 1, i + 2, i + 3};
  }
  return data;
}

MapPointData point_data(double x) {
  MapPointData data;
  data.p_w = Eigen::Vector3d(x, 0, 1);
  data.descriptor = {7, 7, 7, 7};
  return data;
}

TEST(MapReclamation, UnheldCulledObjectsAreFreedAtOnce) {
  Atlas atlas;
  auto map = atlas.create_map();
  const auto& counters = *atlas.counters();
  KeyframeId kf_id = 0;
  MapPointId mp_id = 0, kept_id = 0;
  {
    auto kf = map->new_keyframe(keyframe_data(4));
    auto mp = map->new_map_point(point_data(1));
    auto kept = map->new_map_point(point_data(2));
    ASSERT_TRUE(kf->add_observation(0, mp));
    ASSERT_TRUE(kf->add_observation(1, kept));
    kf_id = kf->id();
    mp_id = mp->id();
    kept_id = kept->id();
  }
  EXPECT_EQ(counters.keyframes().alive(), 1u);
  EXPECT_EQ(counters.map_points().alive(), 2u);

  ASSERT_TRUE(map->cull_map_point(mp_id));  // held by the map and the keyframe slot: both dropped
  EXPECT_EQ(counters.map_points().culled, 1u);
  EXPECT_EQ(counters.map_points().reclaimed, 1u);

  ASSERT_TRUE(map->cull_keyframe(kf_id));
  EXPECT_EQ(counters.keyframes().culled, 1u);
  EXPECT_EQ(counters.keyframes().reclaimed, 1u);
  // The other point is still owned by the map, now without observers.
  EXPECT_EQ(counters.map_points().alive(), 1u);
  EXPECT_EQ(map->map_point(kept_id)->observation_count(), 0u);
}

TEST(MapReclamation, AWorkerKeepsACulledObjectValidUntilItLetsGo) {
  Atlas atlas;
  auto map = atlas.create_map();
  const auto counters = atlas.counters();
  auto kf = map->new_keyframe(keyframe_data(10));
  auto other = map->new_keyframe(keyframe_data(10));
  auto mp = map->new_map_point(point_data(5));
  ASSERT_TRUE(kf->add_observation(3, mp));
  ASSERT_TRUE(other->add_observation(3, mp));
  kf->update_connections(1);
  other->set_parent(kf);
  const KeyframeId kf_id = kf->id();
  const MapPointId mp_id = mp->id();

  std::promise<void> holding, culled, dropped;
  std::shared_future<void> culled_signal = culled.get_future().share();
  struct Seen {
    KeyframeId id = 0;
    std::int64_t timestamp = 0;
    double x = 0, px = 0;
    std::size_t keypoints = 0, observations = 99;
    int map_points = -1;
    bool kf_bad = false, mp_bad = false;
    std::uint64_t descriptor = 0;
  } seen;
  std::thread worker([kf_ref = kf, mp_ref = mp, &holding, culled_signal, &dropped, &seen]() mutable {
    holding.set_value();
    culled_signal.wait();
    // The map has culled both objects; this thread's references keep them valid.
    seen.id = kf_ref->id();
    seen.timestamp = kf_ref->timestamp_ns();
    seen.x = kf_ref->T_w_c().t.x();
    seen.keypoints = kf_ref->features().keypoints.size();
    seen.map_points = kf_ref->map_point_count();
    seen.kf_bad = kf_ref->is_bad();
    seen.px = mp_ref->p_w().x();
    seen.descriptor = mp_ref->descriptor()[0];
    seen.observations = mp_ref->observation_count();
    seen.mp_bad = mp_ref->is_bad();
    kf_ref.reset();
    mp_ref.reset();
    dropped.set_value();
  });
  holding.get_future().wait();
  kf.reset();
  mp.reset();
  ASSERT_TRUE(map->cull_keyframe(kf_id));
  ASSERT_TRUE(map->cull_map_point(mp_id));
  EXPECT_EQ(map->keyframe(kf_id), nullptr);
  EXPECT_EQ(counters->keyframes().culled, 1u);
  EXPECT_EQ(counters->keyframes().reclaimed, 0u);  // the worker still holds them
  EXPECT_EQ(counters->map_points().reclaimed, 0u);
  EXPECT_EQ(other->parent(), nullptr);
  culled.set_value();
  dropped.get_future().wait();
  // Reclaimed the moment the worker let go (before it even finished).
  EXPECT_EQ(counters->keyframes().reclaimed, 1u);
  EXPECT_EQ(counters->map_points().reclaimed, 1u);
  worker.join();
  EXPECT_EQ(seen.id, kf_id);
  EXPECT_EQ(seen.timestamp, 1'000'000'007);
  EXPECT_EQ(seen.x, 1.0);
  EXPECT_EQ(seen.keypoints, 10u);
  EXPECT_EQ(seen.map_points, 0);
  EXPECT_TRUE(seen.kf_bad);
  EXPECT_EQ(seen.px, 5.0);
  EXPECT_EQ(seen.descriptor, 7u);
  EXPECT_EQ(seen.observations, 0u);
  EXPECT_TRUE(seen.mp_bad);
}

// Builds a map with covisibility, spanning tree and loop edges set up.
struct RandomMap {
  std::shared_ptr<Map> map;
  std::vector<KeyframeId> kf_ids;
  std::vector<MapPointId> mp_ids;
};

RandomMap build_random_map(Atlas& atlas, int n_kf, int n_mp, int slots, int obs_per_kf, std::mt19937& rng) {
  RandomMap out;
  out.map = atlas.create_map();
  std::vector<std::shared_ptr<MapPoint>> mps;
  for (int i = 0; i < n_mp; ++i) {
    mps.push_back(out.map->new_map_point(point_data(i)));
    out.mp_ids.push_back(mps.back()->id());
  }
  std::vector<std::shared_ptr<KeyFrame>> kfs;
  for (int k = 0; k < n_kf; ++k) {
    auto kf = out.map->new_keyframe(keyframe_data(static_cast<std::size_t>(slots), &rng));
    // A sliding window of points, as along a trajectory, plus a few random ones.
    const int base = static_cast<int>(static_cast<long>(k) * (n_mp - obs_per_kf) / std::max(1, n_kf - 1));
    int slot = 0;
    for (int p = 0; p < obs_per_kf && slot < slots; ++p) {
      const int idx = (p % 10 == 0) ? std::uniform_int_distribution<int>(0, n_mp - 1)(rng) : base + p;
      if (mps[static_cast<std::size_t>(idx)]->slot_in(kf->id())) continue;
      ORBATLAS_CHECK(kf->add_observation(static_cast<std::size_t>(slot++), mps[static_cast<std::size_t>(idx)]),
                     "add failed");
    }
    kf->update_connections();
    if (!kfs.empty()) {
      const auto best = kf->best_covisibles(1);
      kf->set_parent(!best.empty() && best[0]->id() < kf->id() ? best[0] : kfs.back());
    }
    kfs.push_back(kf);
    out.kf_ids.push_back(kf->id());
  }
  for (int e = 0; e < n_kf / 20; ++e) {
    const auto a = std::uniform_int_distribution<int>(0, n_kf - 1)(rng);
    const auto b = std::uniform_int_distribution<int>(0, n_kf - 1)(rng);
    if (a != b) kfs[static_cast<std::size_t>(a)]->add_loop_edge(kfs[static_cast<std::size_t>(b)]);
  }
  return out;
}

TEST(MapReclamation, RandomMapReclaimsEverythingCulledAndLeaksNothing) {
  std::mt19937 rng(2024);
  std::shared_ptr<ObjectCounters> counters;
  std::weak_ptr<Map> weak_map;
  {
    Atlas atlas;
    counters = atlas.counters();
    RandomMap rm = build_random_map(atlas, 200, 5000, 400, 220, rng);
    weak_map = rm.map;
    const auto created_kf = counters->keyframes().created;
    const auto created_mp = counters->map_points().created;
    EXPECT_EQ(created_kf, 200u);
    EXPECT_EQ(created_mp, 5000u);

    std::shuffle(rm.kf_ids.begin() + 1, rm.kf_ids.end(), rng);  // keep the first keyframe
    std::shuffle(rm.mp_ids.begin(), rm.mp_ids.end(), rng);
    std::size_t next_kf = 1, next_mp = 0;
    for (int round = 0; round < 60; ++round) {
      ASSERT_TRUE(rm.map->cull_keyframe(rm.kf_ids[next_kf++]));
      for (int i = 0; i < 25; ++i) ASSERT_TRUE(rm.map->cull_map_point(rm.mp_ids[next_mp++]));
      if (round % 10 == 9) {
        for (const auto& kf : rm.map->keyframes()) kf->update_connections();
      }
    }
    const auto kfs = counters->keyframes();
    const auto mps = counters->map_points();
    EXPECT_EQ(kfs.culled, 60u);
    EXPECT_EQ(mps.culled, 1500u);
    EXPECT_EQ(kfs.reclaimed, kfs.culled);
    EXPECT_EQ(mps.reclaimed, mps.culled);
    EXPECT_EQ(kfs.alive(), rm.map->keyframe_count());
    EXPECT_EQ(mps.alive(), rm.map->map_point_count());

    // The graph refers only to live objects.
    for (const auto& kf : rm.map->keyframes()) {
      if (auto parent = kf->parent()) {
        EXPECT_FALSE(parent->is_bad());
      }
      for (const auto& edge : kf->connections()) EXPECT_NE(rm.map->keyframe(edge.keyframe), nullptr);
      for (const auto& mp : kf->map_points()) EXPECT_FALSE(mp->is_bad());
      for (const auto id : kf->loop_edge_ids()) EXPECT_NE(rm.map->keyframe(id), nullptr);
    }
  }
  // Atlas gone: no cycle keeps anything alive.
  EXPECT_TRUE(weak_map.expired());
  EXPECT_EQ(counters->keyframes().alive(), 0u);
  EXPECT_EQ(counters->map_points().alive(), 0u);
}

TEST(MapReclamation, ReadersRunWhileTheMapCulls) {
  std::mt19937 rng(99);
  Atlas atlas;
  const auto counters = atlas.counters();
  RandomMap rm = build_random_map(atlas, 60, 1500, 200, 120, rng);
  std::atomic<bool> stop{false};
  std::atomic<long> reads{0};
  std::atomic<int> reading{0};  // readers that have completed a first pass
  std::vector<std::thread> readers;
  for (int t = 0; t < 3; ++t) {
    readers.emplace_back([&, t] {
      std::mt19937 local(static_cast<unsigned>(t));
      long n = 0;
      bool counted = false;
      while (!stop.load()) {
        const auto kfs = rm.map->keyframes();
        if (kfs.empty()) break;
        const auto& kf = kfs[local() % kfs.size()];
        for (const auto& neighbour : kf->best_covisibles(5)) n += static_cast<long>(neighbour->id() % 2);
        for (const auto& mp : kf->map_points()) n += static_cast<long>(mp->observation_count());
        n += count_redundant_scan(*kf).redundant;
        if (auto parent = kf->parent()) n += static_cast<long>(parent->child_ids().size());
        if (t == 0) kf->update_connections();
        ++n;
        if (!counted) {
          counted = true;
          reading.fetch_add(1);
        }
      }
      reads.fetch_add(n);
    });
  }
  std::shuffle(rm.kf_ids.begin(), rm.kf_ids.end(), rng);
  std::shuffle(rm.mp_ids.begin(), rm.mp_ids.end(), rng);
  // Cull only once every reader is inside its loop, so the race is real.
  while (reading.load() < 3) std::this_thread::yield();
  for (int i = 0; i < 30; ++i) {
    rm.map->cull_keyframe(rm.kf_ids[static_cast<std::size_t>(i)]);
    for (int j = 0; j < 20; ++j) rm.map->cull_map_point(rm.mp_ids[static_cast<std::size_t>(i * 20 + j)]);
  }
  stop.store(true);
  for (auto& r : readers) r.join();
  EXPECT_GT(reads.load(), 0);
  EXPECT_EQ(counters->keyframes().reclaimed, 30u);
  EXPECT_EQ(counters->map_points().reclaimed, 600u);
  EXPECT_EQ(counters->keyframes().alive(), rm.map->keyframe_count());
  EXPECT_EQ(counters->map_points().alive(), rm.map->map_point_count());
  for (const auto& kf : rm.map->keyframes()) {
    const auto inc = count_redundant_incremental(*kf);
    const auto scan = count_redundant_scan(*kf);
    EXPECT_EQ(inc.redundant, scan.redundant);
    EXPECT_EQ(inc.map_points, scan.map_points);
  }
}

// A checkpoint snapshots a map's keyframes, then its culled keyframes' anchors.
// A keyframe being culled meanwhile must be in one or both: in neither, the
// checkpoint deleted its row without writing its anchor, and stored frames
// referencing it dangled (found by ServerKill.RandomKills..., after a kill).
TEST(MapReclamation, ASnapshotSeesACulledKeyframeAsAKeyframeOrAnAnchor) {
  std::mt19937 rng(7);
  Atlas atlas;
  RandomMap rm = build_random_map(atlas, 150, 4000, 300, 200, rng);
  const std::vector<KeyframeId> all = rm.kf_ids;
  std::atomic<bool> stop{false};
  std::atomic<int> snapshots{0}, missing{0};
  std::thread checkpoint([&] {
    while (!stop.load()) {
      std::unordered_set<KeyframeId> seen;
      for (const auto& kf : rm.map->keyframes()) seen.insert(kf->id());
      for (const auto& c : rm.map->culled_keyframes()) seen.insert(c.id);
      for (const KeyframeId id : all) missing.fetch_add(seen.count(id) ? 0 : 1);
      snapshots.fetch_add(1);
    }
  });
  while (snapshots.load() < 1) std::this_thread::yield();
  std::shuffle(rm.kf_ids.begin() + 1, rm.kf_ids.end(), rng);  // keep the first keyframe
  for (std::size_t i = 1; i <= 120; ++i) ASSERT_TRUE(rm.map->cull_keyframe(rm.kf_ids[i]));
  stop.store(true);
  checkpoint.join();
  EXPECT_GT(snapshots.load(), 1);
  EXPECT_EQ(missing.load(), 0) << "keyframe ids in neither snapshot, over " << snapshots.load() << " snapshots";
  EXPECT_EQ(rm.map->culled_keyframes().size(), 120u);
}

}  // namespace
}  // namespace orbatlas
