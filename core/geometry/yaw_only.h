#pragma once
// Worlds whose gravity is known (inertial maps) know their roll and pitch; two
// of them, or one before and after a loop correction, differ only by a turn
// about gravity and a move (4 degrees of freedom). A map's gravity points along
// -z when its inertial initialisation turned it so; its refinements leave the
// map where it is and tilt its gravity by what they find instead (a fraction
// of a degree), so the turn is about each world's own up.
#include <Eigen/Core>

#include "core/geometry/pose.h"

namespace orbatlas {

// The turn about z (T_new_old's yaw: atan2(R10, R00)) and the move that take
// `p_old` where T_new_old takes it.
Pose3 yaw_only_transform(const Pose3& T_new_old, const Eigen::Vector3d& p_old);

// The same between worlds whose up (minus gravity's direction) is `up_new` and
// `up_old`: the transform takes up_old to up_new exactly, turns about up_new
// by T_new_old's turn about it, and takes `p_old` where T_new_old takes it.
// With both ups along z it is the one above.
Pose3 yaw_only_transform(const Pose3& T_new_old, const Eigen::Vector3d& p_old, const Eigen::Vector3d& up_new,
                         const Eigen::Vector3d& up_old);

}  // namespace orbatlas
