#include "core/tracking/keyframe_points.h"

#include <algorithm>
#include <utility>
#include <vector>

#include "core/common/error.h"
#include "core/map/map_point_update.h"

namespace orbatlas {

void KeyframePointsOptions::check() const {
  ORBATLAS_CHECK(th_depth_m >= 0.0, "keyframe points: th_depth_m must be >= 0, not " << th_depth_m);
  ORBATLAS_CHECK(min_points >= 0, "keyframe points: min_points must be >= 0, not " << min_points);
}

KeyframePointsResult add_keyframe_points(Map& map, const std::shared_ptr<KeyFrame>& keyframe, Frame& frame,
                                         const Pose3& T_b_c, const ScalePyramid& pyramid,
                                         const KeyframePointsOptions& options) {
  KeyframePointsResult result;
  for (std::size_t i = 0; i < frame.size(); ++i) {
    const auto& mp = frame.map_points[i];
    if (mp && !frame.outlier[i] && !mp->is_bad() && keyframe->try_add_observation(i, mp) == SlotEdit::kDone)
      ++result.observations;
  }

  std::vector<std::pair<float, std::size_t>> by_depth;
  for (std::size_t i = 0; i < frame.size(); ++i)
    if (frame.depth[i] > 0.0f) by_depth.emplace_back(frame.depth[i], i);
  std::sort(by_depth.begin(), by_depth.end());
  const Pose3 T_w_c = frame.T_w_b * T_b_c;
  // One stereo match: counts when its slot ends up holding a point.
  const auto add_stereo_point = [&](float z, std::size_t i) -> bool {
    // What the slot holds now: the tracked point, or what fusion put there
    // since (the frame's own point may have been fused away and culled).
    if (auto held = keyframe->map_point(i); held && !held->is_bad()) {
      frame.map_points[i] = std::move(held);
      return true;
    }
    const auto& tracked = frame.map_points[i];
    if (tracked && !tracked->is_bad() && tracked->observation_count() > 0)
      return true;  // a tracked point kept out of the keyframe as an outlier
    const Keypoint& kp = frame.features.keypoints[i];
    MapPointData pd;
    pd.p_w = T_w_c * (kp.bearing * (static_cast<double>(z) / kp.bearing.z()));
    pd.descriptor = frame.features.descriptors[i];
    auto mp = map.new_map_point(pd);
    mp->set_reference_keyframe(keyframe);
    if (keyframe->try_add_observation(i, mp) != SlotEdit::kDone) {
      // Fusion filled the slot between the look and the add (or culled the
      // keyframe): the new point observes nothing; take it out again and use
      // whatever the slot holds now.
      map.cull_map_point(mp->id());
      ++result.lost_races;
      auto held = keyframe->map_point(i);
      if (!held || held->is_bad()) return false;
      frame.map_points[i] = std::move(held);
      frame.outlier[i] = false;
      return true;
    }
    update_normal_and_distances(*mp, pyramid);
    frame.map_points[i] = std::move(mp);
    frame.outlier[i] = false;
    ++result.created;
    return true;
  };
  int points = 0;
  for (const auto& [z, i] : by_depth) {
    if (add_stereo_point(z, i)) ++points;
    if (!options.all_stereo_points && z > options.th_depth_m && points > options.min_points) break;
  }
  return result;
}

}  // namespace orbatlas
