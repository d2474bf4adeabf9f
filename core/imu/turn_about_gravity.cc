#include "core/imu/turn_about_gravity.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>

namespace orbatlas {

double turn_about_gravity_deg(const std::vector<Eigen::Matrix3d>& R_w_i, const Eigen::Vector3d& gravity_w) {
  if (R_w_i.size() < 2 || !(gravity_w.norm() > 0.0)) return 0.0;
  const Eigen::Vector3d up = -gravity_w.normalized();
  // The IMU axis closest to level on average: its heading is defined best.
  int axis = 0;
  double least = std::numeric_limits<double>::infinity();
  for (int a = 0; a < 3; ++a) {
    double sum = 0.0;
    for (const Eigen::Matrix3d& R : R_w_i) sum += std::abs(up.dot(R.col(a)));
    if (sum < least) {
      least = sum;
      axis = a;
    }
  }
  const auto level = [&](const Eigen::Matrix3d& R) -> Eigen::Vector3d {
    return R.col(axis) - up.dot(R.col(axis)) * up;
  };
  const Eigen::Vector3d first = level(R_w_i.front());
  double lowest = 0.0, highest = 0.0;
  for (const Eigen::Matrix3d& R : R_w_i) {
    const Eigen::Vector3d h = level(R);
    const double heading = std::atan2(up.dot(first.cross(h)), first.dot(h));
    lowest = std::min(lowest, heading);
    highest = std::max(highest, heading);
  }
  return (highest - lowest) * 180.0 / M_PI;
}

}  // namespace orbatlas
