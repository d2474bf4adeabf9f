#include "tests/persistence/test_crash_safety_model.h"

#include <algorithm>
#include <random>

#include "tests/persistence/test_persistence_random_atlas.h"

namespace orbatlas::test {

void apply_crash_step(Atlas& atlas, int k) {
  std::mt19937_64 rng(0x5eed0000ULL + static_cast<std::uint64_t>(k));
  if (k == 1 || k % 6 == 0) atlas.create_map();  // becomes the active map
  const auto map = atlas.active_map();

  const auto before = map->keyframes();
  std::vector<std::shared_ptr<KeyFrame>> fresh;
  for (int i = 0; i < 4; ++i) fresh.push_back(add_random_keyframe(*map, rng, nullptr, 600, i != 3));
  // Points seen by the new keyframes and the last few before them.
  std::vector<std::shared_ptr<KeyFrame>> local = fresh;
  for (std::size_t i = before.size() >= 4 ? before.size() - 4 : 0; i < before.size(); ++i) local.push_back(before[i]);
  std::vector<std::shared_ptr<MapPoint>> points;
  for (int i = 0; i < 1000; ++i) points.push_back(add_random_point(*map, rng));
  observe_randomly(local, points, rng, 2, 3);
  for (std::size_t i = 0; i < fresh.size(); ++i) {
    fresh[i]->set_parent(i > 0 ? fresh[i - 1] : (before.empty() ? nullptr : before.back()));
    fresh[i]->update_connections();
  }
  if (!before.empty()) before.back()->update_connections();

  // A correction moves every keyframe of the map a little, and some points.
  std::normal_distribution<double> small(0.0, 0.01);
  for (const auto& kf : map->keyframes()) {
    Pose3 T = kf->T_w_b();
    T.t += Eigen::Vector3d(small(rng), small(rng), small(rng));
    kf->set_T_w_b(T);
  }
  const auto all_points = map->map_points();
  for (int i = 0; i < 200; ++i) {
    const auto& mp = all_points[rng() % all_points.size()];
    mp->set_p_w(mp->p_w() + Eigen::Vector3d(small(rng), small(rng), small(rng)));
    mp->increase_visible(2);
    mp->increase_found();
  }

  if (k % 3 == 0 && before.size() > 4) before[rng() % before.size()]->add_loop_edge(fresh.back());
  // Culling: points, and an older keyframe (with children: anchors chain).
  for (int i = 0; i < 60; ++i) map->cull_map_point(all_points[rng() % all_points.size()]->id());
  if (before.size() > 6) map->cull_keyframe(before[rng() % (before.size() - 2)]->id());
}

void build_crash_state(Atlas& atlas, int k) {
  for (int step = 1; step <= k; ++step) apply_crash_step(atlas, step);
}

}  // namespace orbatlas::test
