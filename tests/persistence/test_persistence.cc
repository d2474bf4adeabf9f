// Persistent atlas: save / load round trips of whole atlases and of one map
// (on SQLite and on PostgreSQL: PersistenceBackends), saving again over what
// is stored. The schema and its migrations, sessions, jobs and trajectories,
// and the refusals are in test_persistence_schema.cc,
// test_persistence_sessions.cc and test_persistence_refusals.cc.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <string>
#include <vector>

#include "core/common/error.h"
#include "core/map/atlas.h"
#include "core/persistence/atlas_store.h"
#include "tests/support/persistence_backends.h"
#include "tests/persistence/test_persistence_expect.h"
#include "tests/persistence/test_persistence_random_atlas.h"

namespace orbatlas {
namespace {

using namespace test;  // NOLINT: the shared helpers of the persistence tests

// The tests whose bodies run on both backends (tests/support/persistence_backends.h),
// here and in test_persistence_sessions.cc and test_persistence_refusals.cc:
// instantiated once, here, for all of them.
using PersistenceBackends = AtlasBackendTest;
ORBATLAS_PERSISTENCE_BACKENDS(PersistenceBackends);

TEST_P(PersistenceBackends, AtlasRoundTripKeepsEveryField) {
  const Vocabulary& vocabulary = test_vocabulary();
  Atlas original;
  build_atlas(original, vocabulary, 11);
  ASSERT_GT(original.counters()->keyframes().culled, 0u);
  ASSERT_GT(original.counters()->map_points().culled, 0u);
  // The content is non-trivial where the loader has most to get right.
  int asymmetric = 0, redundant = 0;
  for (const auto& kf : original.maps()[0]->keyframes()) {
    redundant += kf->redundant_map_point_count();
    for (const CovisibilityEdge& edge : kf->connections())
      if (const auto other = original.maps()[0]->keyframe(edge.keyframe);
          other && other->weight(kf->id()) != edge.weight)
        ++asymmetric;
  }
  EXPECT_GT(asymmetric, 0);
  EXPECT_GT(redundant, 0);
  {
    AtlasStore store = open_store(vocabulary.hash());
    store.save_atlas(original);
  }
  AtlasStore store = open_store(vocabulary.hash());
  EXPECT_EQ(store.stored_map_ids().size(), 3u);
  Atlas loaded;
  const AtlasLoadReport report = store.load_atlas(loaded, &vocabulary);
  EXPECT_EQ(report.maps, 3u);
  EXPECT_EQ(report.keyframes, count_keyframes(original));
  EXPECT_EQ(report.map_points, count_points(original));
  EXPECT_EQ(report.loop_edges, 2u);  // ka[0]-ka[8] and kb[1]-kb[3]; ka[1]-ka[3] went with ka[3]
  EXPECT_GT(report.covisibility_links, 0u);
  EXPECT_GT(report.observations, 0u);
  EXPECT_EQ(report.culled_keyframes, 4u);  // ka[3], the chain ka[7] -> ka[6], and map b's root
  EXPECT_EQ(report.culled_keyframes, count_culled_keyframes(original));
  expect_atlas_eq(original, loaded, true);

  // Frames anchored to culled keyframes resolve to the same poses after the round
  // trip, through chains of culled parents and from a culled root.
  SessionInfo session;
  session.id = 1;
  store.save_session(session);
  std::vector<FrameAnchor> anchors;
  std::mt19937_64 frame_rng(17);
  for (const auto& map : original.maps())
    for (const Map::CulledKeyframe& c : map->culled_keyframes())
      anchors.push_back(
          {static_cast<TimestampNs>(anchors.size()) * 50'000'000, map->id(), c.id, random_pose(frame_rng)});
  ASSERT_EQ(anchors.size(), 4u);
  store.save_trajectory(session.id, anchors);
  for (const FrameAnchor& a : store.load_trajectory(session.id)) {
    const auto before = original.map(a.map)->keyframe_pose(a.reference);
    const auto after = loaded.map(a.map)->keyframe_pose(a.reference);
    ASSERT_TRUE(before && after) << "keyframe " << a.reference;
    expect_pose_eq(*before * a.T_ref_b, *after * a.T_ref_b, "frame at " + std::to_string(a.t_ns));
  }
  EXPECT_EQ(store.checkpoint_sequence(), 1);  // one save_atlas

  // Nothing loaded is culled; the counters count what was created by loading.
  EXPECT_EQ(loaded.counters()->keyframes().created, count_keyframes(original));
  EXPECT_EQ(loaded.counters()->keyframes().culled, 0u);
  EXPECT_EQ(loaded.counters()->map_points().created, count_points(original));

  // New ids continue above everything the original atlas handed out, including
  // the culled keyframe and point that had the largest ids.
  const auto map_b = loaded.map(original.maps()[1]->id());
  ASSERT_NE(map_b, nullptr);
  KeyframeId max_loaded_kf = 0;
  for (const auto& m : loaded.maps())
    for (const auto& kf : m->keyframes()) max_loaded_kf = std::max(max_loaded_kf, kf->id());
  const KeyframeId new_kf = map_b->new_keyframe(KeyFrameData{})->id();
  EXPECT_EQ(new_kf, original.ids().peek(IdKind::keyframe));
  EXPECT_GT(new_kf, max_loaded_kf + 1);  // the culled last keyframe's id is skipped
  EXPECT_EQ(map_b->new_map_point({})->id(), original.ids().peek(IdKind::map_point));
  EXPECT_EQ(loaded.create_map()->id(), original.ids().peek(IdKind::map));

  // Loading needs an empty atlas and the store's vocabulary.
  EXPECT_THROW(store.load_atlas(loaded, &vocabulary), Error);
  Atlas other;
  std::mt19937_64 rng(5);
  std::vector<std::vector<Descriptor>> images(2);
  for (auto& image : images)
    for (int i = 0; i < 30; ++i) image.push_back(random_descriptor(rng));
  VocabularyTrainingOptions options;
  options.k = 3;
  options.levels = 2;
  options.threads = 1;
  const Vocabulary foreign = Vocabulary::train(images, options);
  ASSERT_NE(foreign.hash(), vocabulary.hash());
  EXPECT_THROW(store.load_atlas(other, &foreign), Error);
  EXPECT_TRUE(other.maps().empty());
}

TEST_P(PersistenceBackends, LoadingWithoutVocabularyLeavesBowEmpty) {
  Atlas original;
  build_atlas(original, test_vocabulary(), 12);
  AtlasStore store = open_store(test_vocabulary().hash());
  store.save_atlas(original);
  Atlas loaded;
  store.load_atlas(loaded, nullptr);
  expect_atlas_eq(original, loaded, false);
}

// One map read again (a replica taking over another's map): the
// stored version, into a detached map the atlas then takes in place of its own
// copy, not recorded as removed.
TEST_P(PersistenceBackends, OneMapIsReadAgainAsStored) {
  Atlas original;
  build_atlas(original, test_vocabulary(), 14);
  AtlasStore store = open_store(test_vocabulary().hash());
  store.save_atlas(original);
  Atlas stored;
  store.load_atlas(stored, &test_vocabulary());
  const auto map = original.maps()[1];
  map->map_points()[0]->set_p_w({4, 5, 6});  // edited after the save: not what is read
  const auto fresh = store.load_map(original, map->id(), &test_vocabulary());
  ASSERT_NE(fresh, nullptr);
  EXPECT_EQ(original.map(map->id()), map);  // not in the atlas yet
  expect_map_eq(*stored.map(map->id()), *fresh, true);
  EXPECT_EQ(store.load_map(original, 424242, &test_vocabulary()), nullptr);
  {
    const auto whole = original.lock_maps_exclusive();
    EXPECT_EQ(original.replace_map(fresh), map);
  }
  EXPECT_EQ(original.map(map->id()), fresh);
  EXPECT_TRUE(original.removed_maps().empty());
  expect_atlas_eq(stored, original, true);
}

TEST_P(PersistenceBackends, SavingAgainReplacesTheStoredMaps) {
  const Vocabulary& vocabulary = test_vocabulary();
  Atlas atlas;
  build_atlas(atlas, vocabulary, 13);
  AtlasStore store = open_store(vocabulary.hash());
  SessionInfo session;
  session.id = 7;
  session.name = "MH_01";
  store.save_session(session);

  const auto map_a = atlas.maps()[0];
  const auto kfs = map_a->keyframes();
  AtlasSaveOptions options;
  options.keyframe_sessions[kfs[0]->id()] = 7;
  options.keyframe_sessions[kfs[2]->id()] = 7;
  store.save_atlas(atlas, options);

  // Edit: cull a keyframe and a point, move a keyframe, change a point.
  ASSERT_TRUE(map_a->cull_keyframe(kfs[1]->id()));
  const auto points = map_a->map_points();
  ASSERT_TRUE(map_a->cull_map_point(points[5]->id()));
  kfs[4]->set_T_w_b(Pose3(Eigen::Quaterniond(0.5, 0.5, -0.5, 0.5), Eigen::Vector3d(1, 2, 3)));
  points[6]->set_p_w({9, 8, 7});
  points[6]->increase_found(3);
  store.save_atlas(atlas);  // no session options: the stored ones stay
  int dead_links = 0;       // see expect_keyframe_eq
  for (const auto& kf : map_a->keyframes())
    for (const CovisibilityEdge& edge : kf->connections()) dead_links += map_a->keyframe(edge.keyframe) ? 0 : 1;
  EXPECT_GT(dead_links, 0);

  Atlas loaded;
  const AtlasLoadReport report = store.load_atlas(loaded, &vocabulary);
  expect_atlas_eq(atlas, loaded, true);
  EXPECT_EQ(loaded.map(map_a->id())->keyframe(kfs[1]->id()), nullptr);
  EXPECT_EQ(report.keyframe_sessions.size(), 2u);
  EXPECT_EQ(report.keyframe_sessions.at(kfs[0]->id()), 7u);
  EXPECT_EQ(report.keyframe_sessions.at(kfs[2]->id()), 7u);

  // A map stored earlier but no longer in the atlas stays stored.
  Atlas small;
  small.add_map(100);
  store.save_atlas(small);
  std::vector<MapId> ids = store.stored_map_ids();
  EXPECT_EQ(ids.size(), 4u);
  EXPECT_EQ(ids.back(), 100u);
  // A keyframe session naming no stored session is refused, and nothing changes.
  AtlasSaveOptions bad;
  bad.keyframe_sessions[kfs[0]->id()] = 999;
  EXPECT_THROW(store.save_atlas(atlas, bad), Error);
  Atlas reloaded;
  EXPECT_EQ(store.load_atlas(reloaded, nullptr).keyframe_sessions.size(), 2u);
}

}  // namespace
}  // namespace orbatlas
