// Map model: ids, atlases side by side, observations and the slots' walk.
// Covisibility, the spanning tree and culling are in test_map_covisibility.cc,
// a map's frame, scale and anchors in test_map_frames.cc.
#include <gtest/gtest.h>

#include <cstddef>
#include <functional>
#include <memory>
#include <set>
#include <thread>
#include <vector>

#include "core/common/error.h"
#include "core/map/atlas.h"
#include "tests/support/map_keyframes.h"

namespace orbatlas {
namespace {

using test::keyframe_data;

TEST(MapModel, IdsAreUniqueAcrossTheMapsOfAnAtlas) {
  Atlas atlas;
  EXPECT_EQ(atlas.active_map(), nullptr);
  const std::vector<std::shared_ptr<Map>> maps = {atlas.create_map(), atlas.create_map(), atlas.create_map()};
  EXPECT_EQ(atlas.active_map(), maps[2]);
  std::set<MapId> map_ids;
  std::set<KeyframeId> kf_ids;
  std::set<MapPointId> mp_ids;
  for (const auto& m : maps) map_ids.insert(m->id());
  for (int i = 0; i < 60; ++i) {
    const auto& m = maps[static_cast<std::size_t>(i) % maps.size()];
    kf_ids.insert(m->new_keyframe(keyframe_data(4))->id());
    mp_ids.insert(m->new_map_point({})->id());
  }
  EXPECT_EQ(map_ids.size(), 3u);
  EXPECT_EQ(kf_ids.size(), 60u);
  EXPECT_EQ(mp_ids.size(), 60u);
  for (const auto& m : maps) EXPECT_EQ(m->keyframe_count(), 20u);
  atlas.set_active(maps[0]->id());
  EXPECT_EQ(atlas.active_map(), maps[0]);
  EXPECT_EQ(atlas.map(maps[1]->id()), maps[1]);
  EXPECT_THROW(atlas.set_active(12345), Error);
  EXPECT_EQ(atlas.maps().size(), 3u);
  // An object of one map cannot be added to another.
  auto kf = KeyFrame::create(1000, maps[1]->id(), keyframe_data(1), atlas.counters());
  EXPECT_THROW(maps[0]->add_keyframe(kf), Error);
  EXPECT_THROW(maps[1]->add_keyframe(maps[1]->keyframes().front()), Error);  // duplicate id
}

TEST(MapModel, IdAllocatorCanBeReseeded) {
  IdAllocator ids;
  EXPECT_EQ(ids.next_keyframe_id(), 0u);
  ids.ensure_above(IdKind::keyframe, 41);
  EXPECT_EQ(ids.next_keyframe_id(), 42u);
  ids.ensure_above(IdKind::keyframe, 10);  // never goes back
  EXPECT_EQ(ids.next_keyframe_id(), 43u);
  EXPECT_EQ(ids.next_map_point_id(), 0u);  // kinds are independent
  EXPECT_EQ(ids.next_map_id(), 0u);
  EXPECT_EQ(ids.peek(IdKind::map), 1u);
}

// Replicas of one database: each hands out ids from its own range,
// and ids it loads from the others' ranges never move its counter.
TEST(MapModel, AConfinedAllocatorStaysInItsRange) {
  IdAllocator ids;
  ids.ensure_above(IdKind::map, 5);  // loaded before confining
  ids.confine(IdKind::map, 100, 103);
  EXPECT_EQ(ids.peek(IdKind::map), 100u);
  ids.ensure_above(IdKind::map, 500);  // another writer's, above the range
  ids.ensure_above(IdKind::map, 7);    // and below it
  EXPECT_EQ(ids.next_map_id(), 100u);
  ids.ensure_above(IdKind::map, 101);  // its own, loaded again
  EXPECT_EQ(ids.next_map_id(), 102u);
  EXPECT_THROW(ids.next_map_id(), Error);  // the range is used up
  EXPECT_EQ(ids.next_keyframe_id(), 0u);   // other kinds are not confined
  IdAllocator again;
  again.ensure_above(IdKind::keyframe, 150);  // ids of its range already handed out
  again.confine(IdKind::keyframe, 100, 200);
  EXPECT_EQ(again.next_keyframe_id(), 151u);
  EXPECT_THROW(again.confine(IdKind::keyframe, 5, 5), Error);
}

TEST(MapModel, TwoAtlasesInOneProcessAreIndependent) {
  struct Result {
    std::vector<KeyframeId> kf_ids;
    std::vector<MapPointId> mp_ids;
    CounterSnapshot kfs, mps;
  };
  auto run = [](int n, Result& result) {
    Atlas atlas;
    auto map = atlas.create_map();
    for (int i = 0; i < n; ++i) {
      auto kf = map->new_keyframe(keyframe_data(8));
      auto mp = map->new_map_point({});
      kf->add_observation(0, mp);
      result.kf_ids.push_back(kf->id());
      result.mp_ids.push_back(mp->id());
    }
    for (int i = 0; i < n; i += 2) map->cull_keyframe(result.kf_ids[static_cast<std::size_t>(i)]);
    result.kfs = atlas.counters()->keyframes();
    result.mps = atlas.counters()->map_points();
  };
  Result a, b;
  std::thread ta(run, 500, std::ref(a));
  std::thread tb(run, 300, std::ref(b));
  ta.join();
  tb.join();
  for (std::size_t i = 0; i < a.kf_ids.size(); ++i) EXPECT_EQ(a.kf_ids[i], i);  // each atlas counts from 0
  for (std::size_t i = 0; i < b.kf_ids.size(); ++i) EXPECT_EQ(b.kf_ids[i], i);
  for (std::size_t i = 0; i < b.mp_ids.size(); ++i) EXPECT_EQ(b.mp_ids[i], i);
  EXPECT_EQ(a.kfs.created, 500u);
  EXPECT_EQ(a.kfs.culled, 250u);
  EXPECT_EQ(a.kfs.reclaimed, 250u);
  EXPECT_EQ(b.kfs.created, 300u);
  EXPECT_EQ(b.kfs.culled, 150u);
  EXPECT_EQ(b.kfs.reclaimed, 150u);
  EXPECT_EQ(a.mps.created, 500u);
  EXPECT_EQ(b.mps.created, 300u);
  EXPECT_EQ(b.mps.reclaimed, 0u);  // the atlas was still alive when read
}

TEST(MapModel, ObservationRulesAreChecked) {
  Atlas atlas;
  auto map = atlas.create_map();
  auto kf = map->new_keyframe(keyframe_data(3));
  auto mp = map->new_map_point({});
  auto other = map->new_map_point({});
  EXPECT_THROW(kf->add_observation(3, mp), Error);
  ASSERT_TRUE(kf->add_observation(0, mp));
  EXPECT_THROW(kf->add_observation(0, other), Error);  // slot taken
  EXPECT_THROW(kf->add_observation(1, mp), Error);     // already in slot 0
  EXPECT_THROW(kf->replace(1, mp), Error);
  EXPECT_TRUE(kf->replace(0, other));
  EXPECT_EQ(mp->observation_count(), 0u);
  EXPECT_EQ(other->slot_in(kf->id()), 0u);
  EXPECT_EQ(kf->erase_slot(0), other);
  EXPECT_EQ(kf->erase_slot(0), nullptr);
  EXPECT_EQ(kf->map_point_count(), 0);
  KeyFrameData bad = keyframe_data(3);
  bad.depth = {1.0f, 2.0f};
  bad.u_right = {1.0f, 2.0f};
  EXPECT_THROW(map->new_keyframe(bad), Error);
}

// The walk tracking's local map makes over many keyframes: each point once,
// none already seen, and the slots' ids in step with every kind of slot edit.
TEST(MapModel, UnseenMapPointsAreEachPointOnceThroughEverySlotEdit) {
  Atlas atlas;
  auto map = atlas.create_map();
  auto a = map->new_keyframe(keyframe_data(6));
  auto b = map->new_keyframe(keyframe_data(6));
  std::vector<std::shared_ptr<MapPoint>> p;
  for (int i = 0; i < 7; ++i) p.push_back(map->new_map_point({}));
  for (std::size_t i = 0; i < 4; ++i) ASSERT_TRUE(a->add_observation(i, p[i]));  // a: p0 p1 p2 p3
  ASSERT_TRUE(b->add_observation(0, p[2]));                                      // b: p2 p3 p4 p5
  ASSERT_TRUE(b->add_observation(1, p[3]));
  ASSERT_TRUE(b->add_observation(2, p[4]));
  ASSERT_TRUE(b->add_observation(5, p[5]));
  // The edits: a's slot 1 emptied, its slot 0 given another point (p6 for p0),
  // b's slot 5 emptied only if it holds p5 (it does), slot 2 not if it holds p0.
  EXPECT_EQ(a->erase_slot(1), p[1]);
  EXPECT_TRUE(a->replace(0, p[6]));
  b->erase_slot_if_holds(5, p[5]);
  b->erase_slot_if_holds(2, p[0]);
  EXPECT_EQ(b->replace_if_holds(1, p[3], p[1]), SlotEdit::kDone);  // b: p2 p1 p4
  FlatIdSet seen;
  seen.clear();
  seen.insert(p[2]->id());  // the frame's own point
  std::vector<MapPointId> walked;
  for (const auto& kf : {a, b})
    kf->for_each_unseen_map_point(seen, [&](const std::shared_ptr<MapPoint>& mp) { walked.push_back(mp->id()); });
  // a: p6 (slot 0), p3 (slot 3); b: p1, p4 (p2 was seen).
  EXPECT_EQ(walked, (std::vector<MapPointId>{p[6]->id(), p[3]->id(), p[1]->id(), p[4]->id()}));
  walked.clear();
  a->for_each_unseen_map_point(seen, [&](const std::shared_ptr<MapPoint>& mp) { walked.push_back(mp->id()); });
  EXPECT_TRUE(walked.empty());  // all seen now
}

}  // namespace
}  // namespace orbatlas
