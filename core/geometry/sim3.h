#pragma once
// Similarity transform S_a_b of 3D space (maps points of frame b into frame a:
// p_a = s * (q * p_b) + t), stored as a unit quaternion, a translation and a
// positive scale. Same naming as Pose3 (docs/conventions.md): S_a_b * S_b_c = S_a_c.
//
// Monocular loop closing needs it because the two ends of a loop can disagree in
// scale (ORB-SLAM's g2o::Sim3); with stereo the scale is 1 and a Sim3 is a Pose3.
#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/geometry/pose.h"

namespace orbatlas {

struct Sim3 {
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  double s = 1.0;

  Sim3() = default;
  // Normalises the quaternion. Throws Error unless the scale is finite and > 0
  // and the quaternion and translation are finite and the quaternion non-zero.
  Sim3(const Eigen::Quaterniond& rotation, const Eigen::Vector3d& translation, double scale = 1.0);
  // The rigid transform as a similarity of scale 1.
  explicit Sim3(const Pose3& pose) : q(pose.q.normalized()), t(pose.t), s(1.0) {}

  // Throws Error unless |s - 1| <= tolerance: dropping a scale silently would
  // distort every point mapped with the result. For the rigid pose of a corrected
  // world->camera similarity (ORB-SLAM's [R, t/s]) see rigid_pose_c_w (sim3_correction.h).
  Pose3 to_pose3(double tolerance = 1e-9) const;

  Eigen::Matrix3d rotation() const { return q.toRotationMatrix(); }
  // [[s R, t], [0, 1]].
  Eigen::Matrix4d matrix() const;

  // S^-1: p_b = (1/s) R^T (p_a - t).
  Sim3 inverse() const;
  // (S_a_b * S_b_c) * p = S_a_b * (S_b_c * p).
  Sim3 operator*(const Sim3& other) const;
  Eigen::Vector3d operator*(const Eigen::Vector3d& p) const { return s * (q * p) + t; }
};

// Rotation angle (rad), translation distance and |log(scale ratio)| of a^-1 * b:
// zero iff a == b; used by the tests and to report convergence.
double sim3_rotation_distance(const Sim3& a, const Sim3& b);
double sim3_translation_distance(const Sim3& a, const Sim3& b);
double sim3_log_scale_distance(const Sim3& a, const Sim3& b);

}  // namespace orbatlas
