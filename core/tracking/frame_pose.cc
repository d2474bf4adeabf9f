#include "core/tracking/frame_pose.h"

#include "core/map/map_point.h"

namespace orbatlas {

namespace {

int optimize(Frame& frame, const FrameCamera& cam, const Pose3& T_b_c, const PoseOptimizerOptions& options,
             const InertialPoseTerm* inertial, std::optional<InertialPoseEstimate>* estimate) {
  PoseOptimizerInput input;
  if (inertial) input.inertial = *inertial;
  input.T_c_w = (frame.T_w_b * T_b_c).inverse();
  input.bf = cam.bf;
  std::vector<std::size_t> keypoint_of;
  input.correspondences.reserve(frame.size());
  keypoint_of.reserve(frame.size());
  for (std::size_t i = 0; i < frame.size(); ++i) {
    frame.outlier[i] = false;
    const auto& mp = frame.map_points[i];
    if (!mp || mp->is_bad()) continue;
    const Keypoint& kp = frame.features.keypoints[i];
    PoseCorrespondence c;
    c.p_w = mp->p_w();
    c.uv = kp.uv.cast<double>();
    if (cam.bf > 0.0 && frame.u_right[i] >= 0.0f) c.u_right = frame.u_right[i];
    c.level_sigma2 = cam.pyramid.sigma2(kp.level);
    input.correspondences.push_back(c);
    keypoint_of.push_back(i);
  }
  if (static_cast<int>(input.correspondences.size()) < options.min_correspondences) return 0;
  const PoseOptimizerResult result = optimize_pose(*cam.camera, input, options);
  for (std::size_t c = 0; c < keypoint_of.size(); ++c) frame.outlier[keypoint_of[c]] = result.inliers[c] == 0;
  frame.T_w_b = result.T_c_w.inverse() * T_b_c.inverse();
  frame.has_pose = true;
  if (estimate) *estimate = result.inertial;
  return result.inlier_count;
}

}  // namespace

int optimize_frame_pose(Frame& frame, const FrameCamera& cam, const Pose3& T_b_c, const PoseOptimizerOptions& options) {
  return optimize(frame, cam, T_b_c, options, nullptr, nullptr);
}

int optimize_frame_pose(Frame& frame, const FrameCamera& cam, const Pose3& T_b_c, const PoseOptimizerOptions& options,
                        const InertialPoseTerm& inertial, std::optional<InertialPoseEstimate>& estimate) {
  return optimize(frame, cam, T_b_c, options, &inertial, &estimate);
}

int discard_outliers(Frame& frame) {
  int kept = 0;
  for (std::size_t i = 0; i < frame.size(); ++i) {
    auto& mp = frame.map_points[i];
    if (!mp) continue;
    if (frame.outlier[i] || mp->is_bad()) {
      mp = nullptr;
      frame.outlier[i] = false;
    } else if (mp->observation_count() > 0) {
      ++kept;
    }
  }
  return kept;
}

}  // namespace orbatlas
