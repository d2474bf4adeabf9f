#include "core/optimization/apply_global_adjustment.h"

#include <deque>
#include <unordered_map>

#include "core/map/map_point_update.h"

namespace orbatlas {

GlobalAdjustmentApplyStats apply_global_adjustment(Map& map, const GlobalBundleAdjustmentResult& result,
                                                   const ScalePyramid& pyramid) {
  GlobalAdjustmentApplyStats stats;
  if (result.frame_epoch != map.frame_epoch()) {  // solved in the map's former frame
    stats.stale = true;
    return stats;
  }
  const auto keyframes = map.keyframes();
  std::unordered_map<KeyframeId, Pose3> now, next;  // body poses before / after the merge
  for (const auto& kf : keyframes) now[kf->id()] = kf->T_w_b();

  // Breadth-first down the spanning tree from its roots, so a parent's new pose
  // is known before its children that the solve did not cover.
  std::deque<std::shared_ptr<KeyFrame>> queue;
  for (const auto& kf : keyframes) {
    const auto parent = kf->parent();
    if (!parent || parent->is_bad() || !now.count(parent->id())) queue.push_back(kf);
  }
  while (!queue.empty()) {
    const auto kf = queue.front();
    queue.pop_front();
    if (next.count(kf->id())) continue;
    if (const auto it = result.T_w_b.find(kf->id()); it != result.T_w_b.end()) {
      next[kf->id()] = it->second;
      ++stats.keyframes_set;
    } else {
      const auto parent = kf->parent();
      if (parent && next.count(parent->id())) {
        next[kf->id()] = next[parent->id()] * (now[parent->id()].inverse() * now[kf->id()]);
        ++stats.keyframes_propagated;
      } else {
        next[kf->id()] = now[kf->id()];
      }
    }
    for (auto& child : kf->children())
      if (!child->is_bad() && now.count(child->id())) queue.push_back(std::move(child));
  }
  for (const auto& kf : keyframes) {
    if (const auto it = next.find(kf->id()); it != next.end()) kf->set_T_w_b(it->second);
    // The velocity is in the keyframe's IMU frame: its new pose carries it.
    if (const auto it = result.imu_states.find(kf->id()); it != result.imu_states.end()) {
      kf->set_imu_state(it->second);
      ++stats.imu_states_set;
    }
  }

  for (const auto& mp : map.map_points()) {
    if (mp->is_bad()) continue;
    if (const auto it = result.p_w.find(mp->id()); it != result.p_w.end()) {
      mp->set_p_w(it->second);
      ++stats.points_set;
    } else if (const auto ref = mp->reference_keyframe_id(); ref && now.count(*ref) && next.count(*ref)) {
      // Same position in the reference keyframe's frame before and after.
      mp->set_p_w(next[*ref] * (now[*ref].inverse() * mp->p_w()));
      ++stats.points_propagated;
    } else {
      continue;
    }
    update_normal_and_distances(*mp, pyramid);
  }
  return stats;
}

}  // namespace orbatlas
