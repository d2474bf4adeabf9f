#pragma once
// Rotation helpers on SO(3): hat, exp, log (rotation vector <-> rotation).
#include <Eigen/Core>
#include <Eigen/Geometry>

namespace orbatlas {

Eigen::Matrix3d hat(const Eigen::Vector3d& w);

// Rotation vector (axis * angle) -> rotation; exact for all angles.
Eigen::Quaterniond so3_exp(const Eigen::Vector3d& w);

// Rotation -> rotation vector with angle in [0, pi].
Eigen::Vector3d so3_log(const Eigen::Quaterniond& q);

// Angle of a rotation in radians, in [0, pi].
double rotation_angle(const Eigen::Quaterniond& q);

}  // namespace orbatlas
