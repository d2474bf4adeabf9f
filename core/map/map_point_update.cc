#include "core/map/map_point_update.h"

#include <algorithm>
#include <vector>

#include "core/common/error.h"

namespace orbatlas {

void update_normal_and_distances(MapPoint& point, const ScalePyramid& pyramid) {
  if (point.is_bad()) return;
  const Eigen::Vector3d p = point.p_w();
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  int n = 0;
  for (const auto& obs : point.observations()) {
    const auto kf = obs.kf.lock();
    if (!kf || kf->is_bad()) continue;
    const Eigen::Vector3d ray = p - kf->T_w_c().t;
    const double norm = ray.norm();
    if (norm <= 0.0) continue;
    normal += ray / norm;
    ++n;
  }
  const auto ref = point.reference_keyframe();
  if (n == 0 || !ref) return;
  const auto slot = point.slot_in(ref->id());
  if (!slot) return;
  const double distance = (p - ref->T_w_c().t).norm();
  const int level = ref->keypoint(*slot).level;
  const double max_distance = distance * pyramid.scale(level);
  const double min_distance = max_distance / pyramid.scale(pyramid.n_levels - 1);
  point.set_normal(normal.normalized());
  point.set_distances(static_cast<float>(min_distance), static_cast<float>(max_distance));
}

void update_descriptor(MapPoint& point) {
  if (point.is_bad()) return;
  std::vector<Descriptor> descriptors;
  for (const auto& obs : point.observations()) {
    const auto kf = obs.kf.lock();
    if (!kf || kf->is_bad() || obs.slot >= kf->features().descriptors.size()) continue;
    descriptors.push_back(kf->features().descriptors[obs.slot]);
  }
  if (descriptors.empty()) return;
  const std::size_t n = descriptors.size();
  std::vector<int> distances(n * n, 0);
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = i + 1; j < n; ++j)
      distances[i * n + j] = distances[j * n + i] = hamming(descriptors[i], descriptors[j]);
  int best_median = 257;
  std::size_t best = 0;
  std::vector<int> row(n);
  for (std::size_t i = 0; i < n; ++i) {
    std::copy(distances.begin() + static_cast<std::ptrdiff_t>(i * n),
              distances.begin() + static_cast<std::ptrdiff_t>((i + 1) * n), row.begin());
    std::nth_element(row.begin(), row.begin() + static_cast<std::ptrdiff_t>((n - 1) / 2), row.end());
    const int median = row[(n - 1) / 2];
    if (median < best_median) {
      best_median = median;
      best = i;
    }
  }
  point.set_descriptor(descriptors[best]);
}

void update_map_point(MapPoint& point, const ScalePyramid& pyramid) {
  update_normal_and_distances(point, pyramid);
  update_descriptor(point);
}

bool add_observation_if_free(KeyFrame& keyframe, std::size_t slot, const std::shared_ptr<MapPoint>& point) {
  if (!point) return false;
  return keyframe.try_add_observation(slot, point) == SlotEdit::kDone;
}

bool replace_map_point(Map& map, const std::shared_ptr<MapPoint>& replaced, const std::shared_ptr<MapPoint>& kept) {
  if (!replaced || !kept || replaced == kept || replaced->is_bad() || kept->is_bad()) return false;
  for (const auto& obs : replaced->observations()) {
    const auto kf = obs.kf.lock();
    if (!kf || kf->is_bad()) continue;
    // One step per slot: another thread (tracking filling a new keyframe, local
    // mapping) may have changed it since the snapshot; then it is left alone.
    const SlotEdit edit = kf->replace_if_holds(obs.slot, replaced, kept);
    if (edit == SlotEdit::kAlreadyObserved) {
      // The keyframe sees `kept` in another slot already: drop this one.
      kf->erase_slot_if_holds(obs.slot, replaced);
    }
  }
  kept->increase_visible(replaced->visible());
  kept->increase_found(replaced->found());
  return map.cull_map_point(replaced->id());
}

}  // namespace orbatlas
