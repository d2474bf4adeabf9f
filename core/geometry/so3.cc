#include "core/geometry/so3.h"

#include <cmath>

namespace orbatlas {

Eigen::Matrix3d hat(const Eigen::Vector3d& w) {
  Eigen::Matrix3d m;
  m << 0.0, -w.z(), w.y(), w.z(), 0.0, -w.x(), -w.y(), w.x(), 0.0;
  return m;
}

Eigen::Quaterniond so3_exp(const Eigen::Vector3d& w) {
  const double theta = w.norm();
  const double half = 0.5 * theta;
  // sin(half)/theta, with its Taylor series near zero.
  const double k = theta < 1e-8 ? 0.5 - theta * theta / 48.0 : std::sin(half) / theta;
  Eigen::Quaterniond q(std::cos(half), k * w.x(), k * w.y(), k * w.z());
  return q.normalized();
}

Eigen::Vector3d so3_log(const Eigen::Quaterniond& q_in) {
  Eigen::Quaterniond q = q_in.normalized();
  if (q.w() < 0.0) q.coeffs() = -q.coeffs();  // shortest rotation
  const Eigen::Vector3d v = q.vec();
  const double s = v.norm();
  if (s < 1e-10) return 2.0 * v / q.w();  // small angle: theta ~ 2 s
  const double theta = 2.0 * std::atan2(s, q.w());
  return theta / s * v;
}

double rotation_angle(const Eigen::Quaterniond& q) { return so3_log(q).norm(); }

}  // namespace orbatlas
