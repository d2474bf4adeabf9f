// Maps in incremental checkpoints (AtlasCheckpointer): a merged map's rows
// moved and the source map deleted, several writers of one database each
// writing only its own maps, which maps a checkpoint changed, and a merge
// landing between a checkpoint's snapshot and its transaction.
#include <gtest/gtest.h>

#include <mutex>
#include <random>
#include <set>
#include <string>
#include <unordered_set>
#include <utility>
#include <vector>

#include "core/persistence/atlas_checkpointer.h"
#include "core/persistence/atlas_store.h"
#include "tests/support/persistence_backends.h"
#include "tests/support/persistence_checkpoints.h"
#include "tests/persistence/test_persistence_expect.h"
#include "tests/persistence/test_persistence_random_atlas.h"

namespace orbatlas {
namespace {

using namespace test;  // NOLINT: the shared helpers of the persistence tests

// A merge (Map::absorb + Atlas::remove_map): the source map's objects move into
// the target with their poses transformed; an incremental checkpoint moves
// their rows and deletes the source map, a full save of a merged atlas deletes
// the stored rows of the map it no longer has; both load equal.
TEST_P(CheckpointTest, MergedMapMovesItsRowsAndLeavesTheFile) {
  Atlas atlas;
  build_atlas(atlas, test_vocabulary(), 33);
  AtlasCheckpointer checkpointer(atlas, location(), test_vocabulary().hash(), manual_only());
  ASSERT_TRUE(checkpointer.checkpoint_now());

  const auto maps = atlas.maps();
  ASSERT_GE(maps.size(), 2u);
  const auto target = maps[0], source = maps[1];
  ASSERT_GT(source->keyframe_count(), 0u);
  const MapId source_id = source->id();
  const std::size_t target_kfs = target->keyframe_count(), source_kfs = source->keyframe_count();
  const std::size_t target_points = target->map_point_count(), source_points = source->map_point_count();
  const auto culled_before = source->culled_keyframes();
  const Pose3 T(Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(0.2, -0.3, 0.9).normalized())),
                Eigen::Vector3d(4.0, -2.0, 0.5));
  const auto kf = source->keyframes().front();
  const auto mp = source->map_points().front();
  const Pose3 kf_before = kf->T_w_b();
  const Eigen::Vector3d p_before = mp->p_w(), n_before = mp->normal();

  {
    const auto whole = atlas.lock_maps_exclusive();
    const Map::AbsorbCounts moved = target->absorb(*source, T);
    EXPECT_EQ(moved.keyframes, source_kfs);
    EXPECT_EQ(moved.map_points, source_points);
    EXPECT_EQ(moved.culled_keyframes, culled_before.size());
    EXPECT_NE(atlas.remove_map(source_id), nullptr);
  }
  EXPECT_EQ(atlas.map(source_id), nullptr);
  EXPECT_EQ(target->keyframe_count(), target_kfs + source_kfs);
  EXPECT_EQ(target->map_point_count(), target_points + source_points);
  EXPECT_EQ(source->keyframe_count(), 0u);
  EXPECT_EQ(kf->map_id(), target->id());
  EXPECT_EQ(mp->map_id(), target->id());
  EXPECT_LT(translation_distance(kf->T_w_b(), T * kf_before), 1e-12);
  EXPECT_LT(rotation_distance(kf->T_w_b(), T * kf_before), 1e-12);
  EXPECT_LT((mp->p_w() - T * p_before).norm(), 1e-12);
  EXPECT_LT((mp->normal() - T.q * n_before).norm(), 1e-12);
  // A frame anchored to a moved keyframe resolves in the target map now.
  const auto located = atlas.locate_frame(FrameAnchor{0, source_id, kf->id(), Pose3()});
  ASSERT_TRUE(located.has_value());
  EXPECT_EQ(located->first, target->id());
  EXPECT_EQ(atlas.map_holding(kf->id()), target->id());
  for (const auto& c : culled_before) {
    const auto pose = target->keyframe_pose(c.id);
    ASSERT_TRUE(pose.has_value()) << "culled keyframe " << c.id;
  }

  ASSERT_TRUE(checkpointer.checkpoint_now());
  expect_file_holds(location(), atlas);
  EXPECT_EQ(AtlasStore::open(location(), test_vocabulary().hash()).stored_map_ids().size(), atlas.maps().size());

  // A full save of the merged atlas into a file that still has both maps.
  const std::string other = another_location("merge_full");
  {
    Atlas before;
    build_atlas(before, test_vocabulary(), 33);
    AtlasStore::open(other, test_vocabulary().hash()).save_atlas(before);
  }
  AtlasStore store = AtlasStore::open(other, test_vocabulary().hash());
  store.save_atlas(atlas);
  EXPECT_EQ(store.stored_map_ids().size(), atlas.maps().size());
  expect_file_holds(other, atlas);
}

// Several writers of one database (replicas): each writes only the
// maps it may write (its ids from a range of its own), and neither writes nor
// deletes the others' rows; a map it may write again after a time it could not
// is rewritten whole, so the file then holds its version exactly.
TEST_P(CheckpointTest, TwoWritersEachWriteOnlyTheirOwnMaps) {
  Atlas a, b;
  build_atlas(a, test_vocabulary(), 41);
  // b's ids come from ranges a never uses.
  b.ids().confine(IdKind::map, 1000, 2000);
  b.ids().confine(IdKind::keyframe, std::uint64_t{1} << 32, std::uint64_t{2} << 32);
  b.ids().confine(IdKind::map_point, std::uint64_t{1} << 40, std::uint64_t{2} << 40);
  build_atlas(b, test_vocabulary(), 42);
  ASSERT_GE(a.maps().size(), 2u);
  const MapId a_own = a.maps()[0]->id(), a_other = a.maps()[1]->id();  // a may not write a_other
  const std::size_t a_maps_at_start = a.maps().size();
  std::mutex ownership_mutex;
  std::set<MapId> a_writes = {a_own};
  std::vector<std::vector<MapId>> a_candidates;
  CheckpointOptions a_options = manual_only();
  a_options.writable_maps = [&](SqlConnection&, const std::vector<MapId>& candidates,
                                const std::unordered_set<MapId>&) {
    std::lock_guard lock(ownership_mutex);
    a_candidates.push_back(candidates);
    std::unordered_set<MapId> out;
    for (const MapId m : candidates)
      if (a_writes.count(m)) out.insert(m);
    return out;
  };
  AtlasCheckpointer ca(a, location(), test_vocabulary().hash(), a_options);
  AtlasCheckpointer cb(b, location(), test_vocabulary().hash(), manual_only());  // every map of its own

  // The file holds a's own map and every map of b, each as its writer has it.
  const auto expect_file = [&](const std::vector<std::pair<const Atlas*, MapId>>& expected) {
    Atlas loaded;
    AtlasStore::open(location(), test_vocabulary().hash()).load_atlas(loaded, &test_vocabulary());
    std::string ids;
    for (const auto& m : loaded.maps()) ids += std::to_string(m->id()) + " ";
    ids += "| expected ";
    for (const auto& [atlas, id] : expected) ids += std::to_string(id) + " ";
    ASSERT_EQ(loaded.maps().size(), expected.size()) << ids;
    for (const auto& [atlas, id] : expected) {
      ASSERT_NE(loaded.map(id), nullptr) << "map " << id;
      expect_map_eq(*atlas->map(id), *loaded.map(id), true);
    }
  };
  std::vector<std::pair<const Atlas*, MapId>> expected = {{&a, a_own}};
  for (const auto& m : b.maps()) expected.push_back({&b, m->id()});
  std::mt19937_64 rng(43);
  for (int round = 0; round < 4; ++round) {
    ASSERT_TRUE(ca.checkpoint_now()) << ca.stats().last_error;
    ASSERT_TRUE(cb.checkpoint_now()) << cb.stats().last_error;
    expect_file(expected);
    if (HasFailure()) return;
    // Edits in every map of both (a's map it may not write included).
    for (Atlas* atlas : {&a, &b}) {
      for (const auto& m : atlas->maps()) {
        atlas->set_active(m->id());
        random_edits(*atlas, rng);
      }
    }
    // random_edits may make new maps: a writes none of them, b all of its own.
    expected.assign({{&a, a_own}});
    for (const auto& m : b.maps()) expected.push_back({&b, m->id()});
  }
  EXPECT_FALSE(a_candidates.empty());
  EXPECT_EQ(a_candidates.front().size(), a_maps_at_start);  // asked about every map it had

  ASSERT_TRUE(cb.checkpoint_now()) << cb.stats().last_error;  // b's last edits
  // a may write a_other now (it took it over): rewritten whole, as a has it.
  {
    std::lock_guard lock(ownership_mutex);
    a_writes.insert(a_other);
  }
  ASSERT_TRUE(ca.checkpoint_now()) << ca.stats().last_error;
  expected.push_back({&a, a_other});
  expect_file(expected);
  // ... and an edit of it afterwards is an ordinary incremental write.
  a.map(a_other)->map_points()[0]->increase_found();
  ASSERT_TRUE(ca.checkpoint_now());
  EXPECT_EQ(ca.stats().last_rows.total(), 1u);
  // a may no longer write a_own (another writer took it): a's edits stay out of the file.
  {
    std::lock_guard lock(ownership_mutex);
    a_writes.erase(a_own);
  }
  const auto kept = ca.stats().commits;
  a.map(a_own)->map_points()[0]->increase_found();
  ASSERT_TRUE(ca.checkpoint_now());
  EXPECT_EQ(ca.stats().commits, kept);  // nothing of it written
  EXPECT_EQ(ca.stats().failures, 0u);
  EXPECT_EQ(cb.stats().failures, 0u);
}

// Replicas watch the maps others change: a checkpoint says, inside its
// transaction, which maps' rows it changed (and only those).
TEST_P(CheckpointTest, ACheckpointSaysWhichMapsItChanged) {
  Atlas atlas;
  build_atlas(atlas, test_vocabulary(), 51);
  const auto maps = atlas.maps();
  ASSERT_GE(maps.size(), 2u);
  std::mutex mutex;
  std::vector<std::vector<MapId>> told;
  CheckpointOptions options = manual_only();
  options.maps_changed = [&](SqlConnection&, const std::vector<MapId>& changed) {
    std::lock_guard lock(mutex);
    told.push_back(changed);
  };
  AtlasCheckpointer checkpointer(atlas, location(), test_vocabulary().hash(), options);
  const auto last = [&] {
    std::lock_guard lock(mutex);
    return told.empty() ? std::vector<MapId>{} : told.back();
  };
  ASSERT_TRUE(checkpointer.checkpoint_now());
  std::vector<MapId> all;
  for (const auto& m : maps) all.push_back(m->id());
  EXPECT_EQ(last(), all);  // the first checkpoint writes every map
  ASSERT_TRUE(checkpointer.checkpoint_now());
  EXPECT_EQ(told.size(), 1u);  // nothing changed: not told
  maps[1]->map_points()[2]->increase_found();
  ASSERT_TRUE(checkpointer.checkpoint_now());
  EXPECT_EQ(last(), std::vector<MapId>{maps[1]->id()});
  maps[0]->keyframes()[1]->set_T_w_b(Pose3(Eigen::Quaterniond(0.5, 0.5, -0.5, 0.5), Eigen::Vector3d(1, 2, 3)));
  const auto kf = maps[1]->keyframes()[0];
  for (std::size_t slot = 0; slot < kf->slot_count(); ++slot)
    if (kf->map_point(slot)) {
      kf->erase_slot(slot);  // an observation
      break;
    }
  ASSERT_TRUE(checkpointer.checkpoint_now());
  EXPECT_EQ(last(), (std::vector<MapId>{maps[0]->id(), maps[1]->id()}));
  EXPECT_EQ(told.size(), 3u);
}

// A merge that lands between a checkpoint's snapshot and its transaction (found
// by ThreadSanitizer's slow runs: the writer read the removed maps after the
// snapshot, and the next checkpoint then inserted rows the file had): that
// checkpoint writes the maps as its snapshot had them, the next one the merge.
TEST_P(CheckpointTest, AMergeBetweenTheSnapshotAndTheTransactionIsWrittenByTheNext) {
  Atlas atlas;
  build_atlas(atlas, test_vocabulary(), 61);
  const auto maps = atlas.maps();
  ASSERT_GE(maps.size(), 2u);
  const auto target = maps[0], source = maps[1];
  bool merge_now = false;
  CheckpointOptions options = manual_only();
  options.before_transaction = [&] {
    if (!merge_now) return;
    merge_now = false;
    const auto whole = atlas.lock_maps_exclusive();
    target->absorb(*source, Pose3());
    atlas.remove_map(source->id());
  };
  AtlasCheckpointer checkpointer(atlas, location(), test_vocabulary().hash(), options);
  ASSERT_TRUE(checkpointer.checkpoint_now());  // both maps written
  source->map_points()[0]->increase_found();   // something to write
  merge_now = true;
  ASSERT_TRUE(checkpointer.checkpoint_now()) << checkpointer.stats().last_error;
  ASSERT_EQ(atlas.map(source->id()), nullptr);
  ASSERT_TRUE(checkpointer.checkpoint_now()) << checkpointer.stats().last_error;
  expect_file_holds(location(), atlas);
  EXPECT_EQ(checkpointer.stats().failures, 0u);
}

}  // namespace
}  // namespace orbatlas
