#pragma once
// Linear two-view triangulation (DLT), shared by local mapping's new points and
// the monocular two-view initialisation.
#include <Eigen/Core>

#include "core/geometry/pose.h"

namespace orbatlas {

// Linear triangulation (DLT) of normalised image coordinates x1, x2 (z = 1) seen
// by cameras T_c1_w, T_c2_w. False when degenerate.
bool triangulate_dlt(const Eigen::Vector2d& x1, const Eigen::Vector2d& x2, const Pose3& T_c1_w, const Pose3& T_c2_w,
                     Eigen::Vector3d* p_w);

}  // namespace orbatlas
