#pragma once
// What the tests of incremental checkpoints (AtlasCheckpointer) share: the
// suite CheckpointTest, run on SQLite and on PostgreSQL (instantiated in
// tests/persistence/test_persistence_checkpoint.cc), checkpoints only on
// request, the file compared with the atlas, and rounds of random edits.
#include <cstdint>
#include <filesystem>
#include <memory>
#include <random>
#include <vector>

#include "core/persistence/atlas_checkpointer.h"
#include "core/persistence/atlas_store.h"
#include "tests/persistence/test_persistence_expect.h"
#include "tests/persistence/test_persistence_random_atlas.h"
#include "tests/support/persistence_backends.h"

namespace orbatlas::test {

inline CheckpointOptions manual_only() {
  CheckpointOptions options;
  options.every_keyframes = 0;
  options.every_seconds = 0;
  return options;
}

// Loads the file through a connection of its own and compares every field.
inline void expect_file_holds(const std::filesystem::path& path, const Atlas& atlas) {
  AtlasStore store = AtlasStore::open(path, test_vocabulary().hash());
  Atlas loaded;
  store.load_atlas(loaded, &test_vocabulary());
  expect_atlas_eq(atlas, loaded, true);
}

template <class T>
inline const std::shared_ptr<T>& pick(const std::vector<std::shared_ptr<T>>& v, std::mt19937_64& rng) {
  return v[rng() % v.size()];
}

// One round of the edits local mapping and loop closing make: new keyframes and
// points, new observations and a replaced / erased slot, new covisibility,
// parents and a loop edge, moved keyframes and points, statistics, culled
// keyframes (with children and parents: chains of anchors) and points, and now
// and then a new map that becomes the active one.
inline void random_edits(Atlas& atlas, std::mt19937_64& rng) {
  if (rng() % 4 == 0) atlas.create_map();
  const auto map = atlas.active_map();
  std::vector<std::shared_ptr<KeyFrame>> fresh;
  for (int i = 0; i < 2; ++i) fresh.push_back(add_random_keyframe(*map, rng, &test_vocabulary(), 60, i == 0));
  auto keyframes = map->keyframes();
  std::vector<std::shared_ptr<MapPoint>> points;
  for (int i = 0; i < 30; ++i) points.push_back(add_random_point(*map, rng));
  observe_randomly(keyframes, points, rng, 2, 4);
  for (const auto& kf : fresh) {
    kf->update_connections(5);
    if (keyframes.size() > fresh.size()) kf->set_parent(keyframes[rng() % (keyframes.size() - fresh.size())]);
  }
  pick(keyframes, rng)->update_connections(5);
  if (keyframes.size() > 3) {
    const auto& a = pick(keyframes, rng);
    const auto& b = pick(keyframes, rng);
    if (a != b) a->add_loop_edge(b);
  }
  // An observation moves to another point, one goes.
  const auto& edited = pick(keyframes, rng);
  for (std::size_t slot = 0; slot < edited->slot_count(); ++slot) {
    if (!edited->map_point(slot)) continue;
    if (rng() % 2) {
      edited->erase_slot(slot);
    } else {
      edited->replace(slot, add_random_point(*map, rng));
    }
    break;
  }
  pick(keyframes, rng)->set_T_w_b(random_pose(rng));
  const auto all_points = map->map_points();
  for (int i = 0; i < 5; ++i) {
    const auto& mp = pick(all_points, rng);
    mp->set_p_w(mp->p_w() + Eigen::Vector3d(0.01, 0, 0));
    mp->increase_visible();
  }
  for (int i = 0; i < 3; ++i) map->cull_map_point(pick(all_points, rng)->id());
  if (keyframes.size() > 4) map->cull_keyframe(pick(keyframes, rng)->id());
}

// Every test runs on SQLite and on PostgreSQL (AtlasCheckpointer opening a
// file or a postgresql:// URI).
class CheckpointTest : public AtlasBackendTest {};

}  // namespace orbatlas::test
