// The tracker's monocular map start (ORB-SLAM's CreateInitialMapMonocular):
// two keyframes and the points the two-view reconstruction triangulated, a
// bundle adjustment of them, and the scale set so that the points' median
// depth in the first keyframe is 1.
#include <algorithm>

#include "core/map/map_point_update.h"
#include "core/optimization/apply_global_adjustment.h"
#include "core/optimization/global_bundle_adjustment.h"
#include "core/tracking/tracker.h"

namespace orbatlas {
namespace {

constexpr int kInitialBundleIterations = 20;  // ORB-SLAM's GlobalBundleAdjustemnt(map, 20)

}  // namespace

bool Tracker::initialize_monocular(Frame& frame) {
  auto start = mono_initializer_->offer(frame);
  if (!start) return false;

  // The reference camera is the map's origin; bodies follow their cameras by T_b_c.
  const Pose3 T_c_b = T_b_c_.inverse();
  Frame& reference = start->reference;
  reference.T_w_b = T_c_b;
  reference.has_pose = true;
  frame.T_w_b = start->T_c2_c1.inverse() * T_c_b;
  frame.has_pose = true;
  std::fill(frame.map_points.begin(), frame.map_points.end(), nullptr);
  std::fill(frame.outlier.begin(), frame.outlier.end(), false);

  const auto kf1 = new_keyframe(reference);
  const auto kf2 = new_keyframe(frame);
  std::vector<std::shared_ptr<MapPoint>> points;
  points.reserve(start->points.size());
  for (const auto& p : start->points) {
    MapPointData data;
    data.p_w = p.p_c1;  // the world is the first camera
    data.descriptor = reference.features.descriptors[p.reference_keypoint];
    auto mp = map_->new_map_point(data);
    if (!kf1->add_observation(p.reference_keypoint, mp) || !kf2->add_observation(p.current_keypoint, mp)) {
      map_->cull_map_point(mp->id());
      continue;
    }
    mp->set_reference_keyframe(kf1);
    update_map_point(*mp, cam_.pyramid);
    points.push_back(std::move(mp));
  }
  kf1->update_connections();
  kf2->update_connections();

  // Nobody else sees this map yet (its keyframes are in no index): the
  // adjustment is applied at once.
  GlobalBundleAdjustmentOptions ba;
  ba.iterations = kInitialBundleIterations;
  ba.origin = kf1->id();
  ba.level_sigma2 = cam_.pyramid.level_sigma2();
  apply_global_adjustment(*map_, global_bundle_adjustment(*map_, *cam_.camera, 0.0, ba), cam_.pyramid);

  // Scale: the median depth of the points in the first camera becomes 1.
  const double median = median_scene_depth(*kf1);
  if (!(median > 0.0) || static_cast<int>(kf1->map_point_count()) < options_.monocular.min_points) {
    // Degenerate after the adjustment: nothing of it stays; the next frames try again.
    for (const auto& mp : points) map_->cull_map_point(mp->id());
    map_->cull_keyframe(kf2->id());
    map_->cull_keyframe(kf1->id());
    std::fill(frame.map_points.begin(), frame.map_points.end(), nullptr);
    frame.has_pose = false;
    return false;
  }
  const Pose3 T_c1_w = kf1->T_w_c().inverse();
  const double s = 1.0 / median;
  const Pose3 T_w_c1 = kf1->T_w_c();  // the identity, up to the solver's rounding
  const auto rescale = [&](const Eigen::Vector3d& p_w) -> Eigen::Vector3d { return T_w_c1 * ((T_c1_w * p_w) * s); };
  Pose3 T_w_c2 = kf2->T_w_c();
  T_w_c2.t = rescale(T_w_c2.t);
  kf2->set_T_w_b(T_w_c2 * T_c_b);
  for (const auto& mp : points) {
    if (mp->is_bad()) continue;
    mp->set_p_w(rescale(mp->p_w()));
    update_map_point(*mp, cam_.pyramid);
  }

  frame.T_w_b = kf2->T_w_b();
  for (const auto& p : start->points)
    if (auto mp = kf2->map_point(p.current_keypoint); mp && !mp->is_bad()) frame.map_points[p.current_keypoint] = mp;

  last_keyframe_.reset();  // the map's first keyframe has no predecessor
  keyframe_made(kf1);
  keyframe_made(kf2);
  local_keyframes_ = {kf1, kf2};
  state_ = TrackingState::kOk;
  velocity_.reset();
  ++monocular_starts_;
  return true;
}

}  // namespace orbatlas
