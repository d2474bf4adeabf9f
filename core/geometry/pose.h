#pragma once
// Rigid transform T_a_b (maps points of frame b into frame a: p_a = T_a_b * p_b),
// stored as a unit quaternion and a translation. See docs/conventions.md.
#include <Eigen/Core>
#include <Eigen/Geometry>

namespace orbatlas {

struct Pose3 {
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();

  Pose3() = default;
  Pose3(const Eigen::Quaterniond& rotation, const Eigen::Vector3d& translation)
      : q(rotation.normalized()), t(translation) {}

  static Pose3 from_matrix(const Eigen::Matrix4d& m);
  Eigen::Matrix4d matrix() const;
  Eigen::Matrix3d rotation() const { return q.toRotationMatrix(); }

  Pose3 inverse() const;
  Pose3 operator*(const Pose3& other) const { return Pose3(q * other.q, q * other.t + t); }
  Eigen::Vector3d operator*(const Eigen::Vector3d& p) const { return q * p + t; }
};

// Geodesic interpolation: alpha = 0 gives a, 1 gives b (slerp + linear).
Pose3 interpolate(const Pose3& a, const Pose3& b, double alpha);

// Translation distance and rotation angle (radians) of a^-1 * b.
double translation_distance(const Pose3& a, const Pose3& b);
double rotation_distance(const Pose3& a, const Pose3& b);

}  // namespace orbatlas
