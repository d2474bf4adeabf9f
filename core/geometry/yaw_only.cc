#include "core/geometry/yaw_only.h"

#include <Eigen/Geometry>
#include <cmath>

namespace orbatlas {

Pose3 yaw_only_transform(const Pose3& T_new_old, const Eigen::Vector3d& p_old) {
  const Eigen::Matrix3d R = T_new_old.q.normalized().toRotationMatrix();
  const Eigen::Quaterniond yaw(Eigen::AngleAxisd(std::atan2(R(1, 0), R(0, 0)), Eigen::Vector3d::UnitZ()));
  return Pose3(yaw, T_new_old * p_old - yaw * p_old);
}

Pose3 yaw_only_transform(const Pose3& T_new_old, const Eigen::Vector3d& p_old, const Eigen::Vector3d& up_new,
                         const Eigen::Vector3d& up_old) {
  // Each world's level frame (its z along the world's up, the least turn from
  // the world's axes); between the level frames the transform is a yaw.
  const Eigen::Quaterniond L_new = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), up_new);
  const Eigen::Quaterniond L_old = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), up_old);
  const Eigen::Matrix3d R = (L_new.conjugate() * T_new_old.q.normalized() * L_old).toRotationMatrix();
  const Eigen::Quaterniond yaw(Eigen::AngleAxisd(std::atan2(R(1, 0), R(0, 0)), Eigen::Vector3d::UnitZ()));
  const Eigen::Quaterniond q = (L_new * yaw * L_old.conjugate()).normalized();
  return Pose3(q, T_new_old * p_old - q * p_old);
}

}  // namespace orbatlas
