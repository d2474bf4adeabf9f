#include "core/geometry/yaw_only.h"

#include <Eigen/Geometry>
#include <cmath>

namespace orbatlas {

Pose3 yaw_only_transform(const Pose3& T_new_old, const Eigen::Vector3d& p_old) {
  const Eigen::Matrix3d R = T_new_old.q.normalized().toRotationMatrix();
  const Eigen::Quaterniond yaw(Eigen::AngleAxisd(std::atan2(R(1, 0), R(0, 0)), Eigen::Vector3d::UnitZ()));
  return Pose3(yaw, T_new_old * p_old - yaw * p_old);
}

}  // namespace orbatlas
