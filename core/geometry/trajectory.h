#pragma once
// A trajectory: poses T_w_b at nanosecond timestamps, strictly increasing.
#include <optional>
#include <vector>

#include "core/common/timestamp.h"
#include "core/geometry/pose.h"

namespace orbatlas {

struct StampedPose {
  TimestampNs t_ns = 0;
  Pose3 pose;  // T_w_b
};

using Trajectory = std::vector<StampedPose>;

// Pose at time t: the sample itself when one lies within exact_tol_ns, otherwise
// interpolated between the two samples around t if they are at most max_gap_ns
// apart. Empty when t is outside the trajectory or inside a larger gap.
std::optional<Pose3> pose_at(const Trajectory& trajectory, TimestampNs t, TimestampNs max_gap_ns,
                             TimestampNs exact_tol_ns = 1000);

// Throws DataError unless timestamps strictly increase.
void check_strictly_increasing(const Trajectory& trajectory, const char* what);

// Several trajectories (e.g. sessions in one world frame) as one, in time
// order. Throws DataError, naming `what`, when two poses share a timestamp
// (recordings that overlap in time cannot be joined).
Trajectory join_trajectories(const std::vector<Trajectory>& parts, const char* what);

// The trajectory of a frame rigidly attached to the body: each T_w_b * T_b_x
// (e.g. the camera's, x = c, to compare with what a monocular session reports).
Trajectory attached_frame(const Trajectory& trajectory, const Pose3& T_b_x);

}  // namespace orbatlas
