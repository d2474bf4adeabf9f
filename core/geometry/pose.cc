#include "core/geometry/pose.h"

#include "core/geometry/so3.h"

namespace orbatlas {

Pose3 Pose3::from_matrix(const Eigen::Matrix4d& m) {
  // Re-orthonormalise: calibration files carry rotations with ~1e-9 errors.
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(m.topLeftCorner<3, 3>(), Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d r = svd.matrixU() * svd.matrixV().transpose();
  if (r.determinant() < 0) {
    Eigen::Matrix3d u = svd.matrixU();
    u.col(2) *= -1.0;
    r = u * svd.matrixV().transpose();
  }
  return Pose3(Eigen::Quaterniond(r), m.topRightCorner<3, 1>());
}

Eigen::Matrix4d Pose3::matrix() const {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = q.toRotationMatrix();
  m.topRightCorner<3, 1>() = t;
  return m;
}

Pose3 Pose3::inverse() const {
  const Eigen::Quaterniond qi = q.conjugate();
  return Pose3(qi, -(qi * t));
}

Pose3 interpolate(const Pose3& a, const Pose3& b, double alpha) {
  return Pose3(a.q.slerp(alpha, b.q), (1.0 - alpha) * a.t + alpha * b.t);
}

double translation_distance(const Pose3& a, const Pose3& b) { return (a.inverse() * b).t.norm(); }

double rotation_distance(const Pose3& a, const Pose3& b) { return rotation_angle(a.q.conjugate() * b.q); }

}  // namespace orbatlas
