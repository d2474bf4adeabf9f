#pragma once
// One 3D-3D match between two keyframes, the input of the loop-closing Sim3
// estimators (Sim3Solver RANSAC, refine_sim3): a map point of keyframe 1 and a
// map point of keyframe 2 believed to be the same physical point, each with the
// keypoint that observes it in its own keyframe.
//
// Points are given in their keyframe's camera frame (p_c1 = T_c1_w1 * p_w1 with
// map 1's world; p_c2 likewise with map 2's world, possibly of another scale), so
// the estimators need no world or pose: the caller transforms once
// (match_from_world). The estimated S_1_2 maps camera-2 coordinates into camera 1:
// p_c1 = S_1_2 * p_c2.
#include <Eigen/Core>

#include "core/geometry/pose.h"

namespace orbatlas {

struct Sim3Match {
  Eigen::Vector3d p_c1 = Eigen::Vector3d::Zero();  // map point of keyframe 1, camera-1 frame
  Eigen::Vector3d p_c2 = Eigen::Vector3d::Zero();  // matched map point of keyframe 2, camera-2 frame
  Eigen::Vector2d uv1 = Eigen::Vector2d::Zero();   // keypoint of p_c1 in image 1 (camera 1's model image)
  Eigen::Vector2d uv2 = Eigen::Vector2d::Zero();   // keypoint of p_c2 in image 2
  double level_sigma2_1 = 1.0;                     // sigma^2 of uv1's pyramid level
  double level_sigma2_2 = 1.0;                     // sigma^2 of uv2's pyramid level
};

// The match of world points p_w1 (map of keyframe 1, pose T_c1_w1) and p_w2 (map of
// keyframe 2, pose T_c2_w2).
inline Sim3Match match_from_world(const Pose3& T_c1_w1, const Eigen::Vector3d& p_w1, const Eigen::Vector2d& uv1,
                                  double level_sigma2_1, const Pose3& T_c2_w2, const Eigen::Vector3d& p_w2,
                                  const Eigen::Vector2d& uv2, double level_sigma2_2) {
  return Sim3Match{T_c1_w1 * p_w1, T_c2_w2 * p_w2, uv1, uv2, level_sigma2_1, level_sigma2_2};
}

}  // namespace orbatlas
