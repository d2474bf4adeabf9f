#pragma once
// Gravity-aligned worlds (inertial maps: gravity along -z) know their roll and
// pitch; two of them, or one before and after a loop correction, differ only
// by a turn about z and a move (4 degrees of freedom).
#include <Eigen/Core>

#include "core/geometry/pose.h"

namespace orbatlas {

// The turn about z (T_new_old's yaw: atan2(R10, R00)) and the move that take
// `p_old` where T_new_old takes it.
Pose3 yaw_only_transform(const Pose3& T_new_old, const Eigen::Vector3d& p_old);

}  // namespace orbatlas
