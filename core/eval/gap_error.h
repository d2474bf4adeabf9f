#pragma once
// The error of a trajectory across a gap in its images (the issue-19 blackout:
// frames carried by the IMU alone): the trajectory is aligned (SE3) on its
// poses outside the gap, then the error is read at its last pose inside the gap
// and at its first pose after it.
#include <optional>

#include "core/common/timestamp.h"
#include "core/geometry/trajectory.h"

namespace orbatlas {

struct GapError {
  double at_end_m = 0.0;          // at the last estimated pose inside [from, to)
  TimestampNs end_t_ns = 0;       // its time
  std::optional<double> after_m;  // at the first estimated pose from `to` on
};

// None when no estimated pose inside the gap has ground truth within
// `max_gap_ns`, or fewer than three outside it do (no alignment).
std::optional<GapError> gap_error(const Trajectory& estimate, const Trajectory& ground_truth, TimestampNs from_ns,
                                  TimestampNs to_ns, TimestampNs max_gap_ns = 20'000'000);

}  // namespace orbatlas
