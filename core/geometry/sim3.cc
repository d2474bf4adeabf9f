#include "core/geometry/sim3.h"

#include <cmath>

#include "core/common/error.h"
#include "core/geometry/so3.h"

namespace orbatlas {

Sim3::Sim3(const Eigen::Quaterniond& rotation, const Eigen::Vector3d& translation, double scale)
    : q(rotation), t(translation), s(scale) {
  ORBATLAS_CHECK(std::isfinite(scale) && scale > 0.0, "Sim3: scale must be finite and positive, got " << scale);
  ORBATLAS_CHECK(rotation.coeffs().allFinite() && rotation.norm() > 0.0,
                 "Sim3: invalid quaternion " << rotation.coeffs().transpose());
  ORBATLAS_CHECK(translation.allFinite(), "Sim3: translation not finite: " << translation.transpose());
  q.normalize();
}

Pose3 Sim3::to_pose3(double tolerance) const {
  ORBATLAS_CHECK(std::abs(s - 1.0) <= tolerance, "Sim3::to_pose3: scale " << s << " is not 1");
  return Pose3(q, t);
}

Eigen::Matrix4d Sim3::matrix() const {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = s * q.toRotationMatrix();
  m.topRightCorner<3, 1>() = t;
  return m;
}

Sim3 Sim3::inverse() const {
  const Eigen::Quaterniond qi = q.conjugate();
  return Sim3(qi, -(qi * t) / s, 1.0 / s);
}

Sim3 Sim3::operator*(const Sim3& other) const { return Sim3(q * other.q, s * (q * other.t) + t, s * other.s); }

double sim3_rotation_distance(const Sim3& a, const Sim3& b) { return rotation_angle(a.q.conjugate() * b.q); }

double sim3_translation_distance(const Sim3& a, const Sim3& b) { return (a.inverse() * b).t.norm(); }

double sim3_log_scale_distance(const Sim3& a, const Sim3& b) { return std::abs(std::log(b.s / a.s)); }

}  // namespace orbatlas
