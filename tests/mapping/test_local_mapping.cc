// Local mapping on exact synthetic scenes: the spanning tree's parents, errors
// contained per keyframe (and a session failed by a long run of them), waits
// for a keyframe's adjustment, sessions sharing a mapper, and the mappers of
// the maps (MappingWorkers).
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <future>
#include <optional>
#include <string>
#include <utility>

#include "core/map/atlas.h"
#include "core/mapping/local_mapper.h"
#include "core/slam/mapping_workers.h"
#include "tests/support/mapping_scene.h"

namespace orbatlas {
namespace {

using test::at;
using test::keyframe_data;
using test::make_scene;
using test::Scene;

// Tracking adds a keyframe's observations before local mapping processes it, so
// a newer keyframe waiting in the queue can be an older one's best covisible.
// Parents are chosen among older keyframes only, so the spanning tree stays a
// tree (a 2-cycle made culling fail on full MH_03).
TEST(LocalMapping, SpanningTreeParentIsAnOlderKeyframe) {
  const Scene s = make_scene(200, 11);
  Atlas atlas;
  auto map = atlas.create_map();
  std::vector<std::size_t> idx[3];
  std::shared_ptr<KeyFrame> kfs[3];
  for (int k = 0; k < 3; ++k) kfs[k] = map->new_keyframe(keyframe_data(s, at(0.1 * k, 0, 0), &idx[k]));
  auto slot_of = [](const std::vector<std::size_t>& v, std::size_t point) -> std::optional<std::size_t> {
    const auto it = std::find(v.begin(), v.end(), point);
    if (it == v.end()) return std::nullopt;
    return static_cast<std::size_t>(it - v.begin());
  };
  // The origin and the middle keyframe share 20 points; the middle and the newest 60.
  int shared01 = 0, shared12 = 0;
  for (std::size_t p = 0; p < s.points.size(); ++p) {
    const auto a = slot_of(idx[0], p), b = slot_of(idx[1], p), c = slot_of(idx[2], p);
    const bool with_origin = shared01 < 20 && a && b;
    const bool with_newest = !with_origin && shared12 < 60 && b && c;
    if (!with_origin && !with_newest) continue;
    MapPointData d;
    d.p_w = s.points[p];
    d.descriptor = s.descriptors[p];
    auto mp = map->new_map_point(d);
    kfs[1]->add_observation(*b, mp);
    kfs[with_origin ? 0 : 2]->add_observation(with_origin ? *a : *c, mp);
    mp->set_reference_keyframe(kfs[1]);
    (with_origin ? shared01 : shared12)++;
  }
  ASSERT_EQ(shared01, 20);
  ASSERT_EQ(shared12, 60);

  LocalMapperOptions o;
  o.run_bundle_adjustment = false;
  o.run_culling = false;
  LocalMapper mapper(atlas, s.cam(), o);
  for (const auto& kf : kfs) {
    mapper.insert(kf);
    mapper.wait_until_idle();
  }
  mapper.finish();
  EXPECT_EQ(kfs[0]->parent(), nullptr);  // the origin
  EXPECT_EQ(kfs[1]->parent(), kfs[0]);   // not the newer kfs[2], its best covisible
  ASSERT_NE(kfs[2]->parent(), nullptr);  // older: kfs[0] or kfs[1] (triangulation adds shared points)
  EXPECT_LT(kfs[2]->parent()->id(), kfs[2]->id());
}

// An error while processing one keyframe (here: in the processed-keyframe
// listener, where loop closing is fed) is contained: counted, the mapper goes
// on with the next keyframe, the session sees nothing. Only a long run of
// failures, a map that cannot be worked on, reaches the session.
TEST(LocalMapping, AnErrorInOneKeyframeIsCountedAndMappingGoesOn) {
  const Scene s = make_scene(200, 13);
  Atlas atlas;
  auto map = atlas.create_map();
  std::vector<std::shared_ptr<KeyFrame>> kfs;
  for (int k = 0; k < 6; ++k) {
    std::vector<std::size_t> idx;
    kfs.push_back(map->new_keyframe(keyframe_data(s, at(0.05 * k, 0, 0), &idx)));
  }
  LocalMapperOptions o;
  o.run_bundle_adjustment = false;
  o.run_culling = false;
  LocalMapper mapper(atlas, s.cam(), o);
  std::vector<KeyframeId> listened;
  mapper.set_processed_listener([&](const std::shared_ptr<KeyFrame>& kf) {
    listened.push_back(kf->id());
    if (kf->id() % 2 == 1) throw Error("injected failure in keyframe " + std::to_string(kf->id()));
  });
  for (const auto& kf : kfs) {
    EXPECT_NO_THROW(mapper.insert(kf));
    EXPECT_NO_THROW(mapper.wait_until_idle());
  }
  EXPECT_NO_THROW(mapper.finish());
  EXPECT_EQ(listened.size(), kfs.size());  // every keyframe was processed
  const LocalMapperStats stats = mapper.stats();
  EXPECT_EQ(stats.keyframes, kfs.size());
  EXPECT_EQ(stats.errors.errors, 3u);
  EXPECT_FALSE(stats.errors.fatal);
  EXPECT_NE(stats.errors.last.find("injected failure in keyframe 5"), std::string::npos) << stats.errors.last;
  // The map is intact: every keyframe still in it, each one's parent older.
  EXPECT_EQ(map->keyframe_count(), kfs.size());
  for (std::size_t k = 1; k < kfs.size(); ++k) {
    if (kfs[k]->parent()) {
      EXPECT_LT(kfs[k]->parent()->id(), kfs[k]->id());
    }
  }
}

// The first keyframe a mapper processes stays in processing (in its processed
// listener, after its local BA and culling) until `release` is set; `entered`
// is set once it is there. Declared before the mapper, which calls it.
struct FirstKeyframeHold {
  std::promise<void> entered, release;
  std::shared_future<void> released = release.get_future().share();
  bool first = true;
  void attach(LocalMapper& mapper) {
    mapper.set_processed_listener([this](const std::shared_ptr<KeyFrame>&) {
      if (!std::exchange(first, false)) return;
      entered.set_value();
      released.wait();
    });
  }
};

// Tracking's wait for its last keyframe (Tracker::wait_for_mapping): a
// keyframe counts as adjusted once its local BA and culling are done, before
// the rest of its processing (here the listener holds it); one queued behind
// another session's keyframe is not adjusted until it has been processed.
TEST(LocalMapping, AKeyframeIsAdjustedBeforeItsProcessingEndsAndWaitsAreBounded) {
  const Scene s = make_scene(200, 29);
  Atlas atlas;
  auto map = atlas.create_map();
  LocalMapperOptions o;
  o.run_culling = false;
  FirstKeyframeHold hold;
  LocalMapper mapper(atlas, s.cam(), o);
  hold.attach(mapper);
  using std::chrono::milliseconds;
  EXPECT_TRUE(mapper.wait_until_adjusted(1, milliseconds(0)));  // nothing handed in
  std::vector<std::size_t> idx;
  ASSERT_TRUE(mapper.insert(map->new_keyframe(keyframe_data(s, at(0.0, 0, 0), &idx)), 1));
  ASSERT_TRUE(mapper.insert(map->new_keyframe(keyframe_data(s, at(0.05, 0, 0), &idx)), 2));
  hold.entered.get_future().wait();
  EXPECT_TRUE(mapper.wait_until_adjusted(1, milliseconds(0)));  // adjusted, still in processing
  EXPECT_FALSE(mapper.idle(1));
  const auto start = std::chrono::steady_clock::now();
  EXPECT_FALSE(mapper.wait_until_adjusted(2, milliseconds(50)));  // queued behind it: the wait is cut
  EXPECT_GE(std::chrono::steady_clock::now() - start, milliseconds(50));
  hold.release.set_value();
  EXPECT_TRUE(mapper.wait_until_adjusted(2, milliseconds(10000)));
  mapper.finish();
  EXPECT_EQ(mapper.stats().keyframes, 2u);
}

// Sessions sharing a mapper (sources): a keyframe of one in processing makes
// the mapper busy for that session only, so another session still makes its
// keyframes as it would alone (ORB-SLAM's AcceptKeyFrames, per session).
TEST(LocalMapping, IdleIsPerSourceWhenSessionsShareAMapper) {
  const Scene s = make_scene(200, 23);
  Atlas atlas;
  auto map = atlas.create_map();
  LocalMapperOptions o;
  o.run_bundle_adjustment = false;
  o.run_culling = false;
  FirstKeyframeHold hold;
  LocalMapper mapper(atlas, s.cam(), o);
  hold.attach(mapper);
  std::vector<std::size_t> idx;
  EXPECT_TRUE(mapper.idle(1));
  EXPECT_TRUE(mapper.insert(map->new_keyframe(keyframe_data(s, at(0.0, 0, 0), &idx)), 1));
  hold.entered.get_future().wait();
  EXPECT_FALSE(mapper.idle());   // the mapper is working
  EXPECT_FALSE(mapper.idle(1));  // on source 1's keyframe
  EXPECT_TRUE(mapper.idle(2));   // source 2 has nothing pending
  EXPECT_TRUE(mapper.insert(map->new_keyframe(keyframe_data(s, at(0.05, 0, 0), &idx)), 2));
  EXPECT_FALSE(mapper.idle(2));  // queued behind source 1's
  EXPECT_EQ(mapper.queued(), 1u);
  hold.release.set_value();
  mapper.wait_until_idle();
  EXPECT_TRUE(mapper.idle(1));
  EXPECT_TRUE(mapper.idle(2));
  EXPECT_TRUE(mapper.idle());
  mapper.finish();
  EXPECT_EQ(mapper.stats().keyframes, 2u);
}

TEST(LocalMapping, FailingOnEveryKeyframeFailsTheSessionAtLast) {
  const Scene s = make_scene(100, 17);
  Atlas atlas;
  auto map = atlas.create_map();
  LocalMapperOptions o;
  o.run_bundle_adjustment = false;
  o.run_culling = false;
  LocalMapper mapper(atlas, s.cam(), o);
  mapper.set_processed_listener([](const std::shared_ptr<KeyFrame>&) { throw Error("the map is broken"); });
  bool failed = false;
  for (int k = 0; k < 40 && !failed; ++k) {
    std::vector<std::size_t> idx;
    try {
      mapper.insert(map->new_keyframe(keyframe_data(s, at(0.01 * k, 0, 0), &idx)));
      mapper.wait_until_idle();
    } catch (const WorkerFailed& e) {
      failed = true;
      EXPECT_NE(std::string(e.what()).find("local mapping failed 20 times in a row"), std::string::npos) << e.what();
      EXPECT_EQ(k, 19);  // raised by the wait after the 20th keyframe
    }
  }
  EXPECT_TRUE(failed);
  EXPECT_TRUE(mapper.stats().errors.fatal);
  EXPECT_THROW(mapper.finish(), WorkerFailed);
}

// Local mapping belongs to the map: sessions (sinks) tracking in one map feed
// its one mapper; a map paused for a loop correction takes no keyframes, also
// before it has a mapper; a merge hands the merged map's mapping over; a map
// nobody maps lets its mapper go and gets a new one with its next keyframe.
TEST(MappingWorkers, SessionsInOneMapFeedOneMapper) {
  const Scene s = make_scene(200, 19);
  Atlas atlas;
  auto a = atlas.create_map();
  auto b = atlas.create_map();
  MappingWorkersOptions o;
  o.mapper.run_bundle_adjustment = false;
  o.mapper.run_culling = false;
  o.loop_closing = false;
  MappingWorkers workers(atlas, s.cam(), o);
  const auto first = workers.attach();
  const auto second = workers.attach();
  const auto keyframe = [&s](Map& map, double x) {
    std::vector<std::size_t> idx;
    return map.new_keyframe(keyframe_data(s, at(x, 0, 0), &idx));
  };
  EXPECT_TRUE(first->accepting(a->id()));
  EXPECT_TRUE(first->idle(a->id()));  // no mapper yet: nothing queued
  for (int k = 0; k < 3; ++k) {
    first->insert(keyframe(*a, 0.05 * k));
    second->insert(keyframe(*a, 0.05 * k + 0.02));
  }
  EXPECT_EQ(workers.mapped_maps(), (std::vector<MapId>{a->id()}));  // one mapper for both sessions
  second->insert(keyframe(*b, 0.5));
  EXPECT_EQ(workers.mapped_maps(), (std::vector<MapId>{a->id(), b->id()}));
  workers.wait_until_idle();
  EXPECT_EQ(workers.mapping_stats().keyframes, 7u);

  workers.pause(a->id());
  EXPECT_FALSE(first->accepting(a->id()));
  EXPECT_TRUE(second->accepting(b->id()));
  workers.resume(a->id());
  EXPECT_TRUE(first->accepting(a->id()));
  const MapId later = a->id() + 100;  // a map without a mapper stays paused too
  workers.pause(later);
  EXPECT_FALSE(first->accepting(later));
  workers.resume(later);
  EXPECT_TRUE(first->accepting(later));

  // b merged into a (both paused, as the loop closer does): b's mapping ends.
  workers.pause(a->id());
  workers.pause(b->id());
  workers.merged(b->id(), a->id());
  workers.resume(b->id());
  workers.resume(a->id());
  EXPECT_EQ(workers.mapped_maps(), (std::vector<MapId>{a->id()}));
  // Nobody maps a now: its mapper goes; a keyframe later starts a new one.
  workers.retire(a->id());
  EXPECT_TRUE(workers.mapped_maps().empty());
  first->insert(keyframe(*a, 0.3));
  EXPECT_EQ(workers.mapped_maps(), (std::vector<MapId>{a->id()}));
  workers.finish();
  const LocalMapperStats stats = workers.mapping_stats();
  EXPECT_EQ(stats.keyframes, 8u);  // every mapper's figures, the retired ones' too
  EXPECT_EQ(stats.errors.errors, 0u);
  EXPECT_THROW(first->insert(keyframe(*a, 0.4)), Error);
  EXPECT_THROW(workers.attach(), Error);
}

}  // namespace
}  // namespace orbatlas
