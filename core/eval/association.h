#pragma once
// Associating estimated poses with ground truth by timestamp.
#include <cstddef>
#include <vector>

#include "core/geometry/trajectory.h"

namespace orbatlas {

struct AssociationOptions {
  // Ground-truth samples further apart than this are not interpolated between.
  TimestampNs max_gap_ns = 100'000'000;  // 0.1 s
  // A ground-truth sample this close to the estimate's timestamp is used as is.
  TimestampNs exact_tol_ns = 1'000;  // 1 us

  // Throws Error naming the first value out of range.
  void check() const;
};

struct PosePair {
  TimestampNs t_ns = 0;
  Pose3 estimate;      // T_w_b of the estimate (its own world frame)
  Pose3 ground_truth;  // T_w_b of the ground truth at t_ns (exact sample or interpolated)
};

struct Association {
  std::vector<PosePair> pairs;  // in the estimate's time order
  std::size_t unmatched = 0;    // estimates outside the ground truth or inside one of its gaps
};

// Every estimated pose gets the ground-truth pose at its timestamp (pose_at):
// unmatched estimates are counted, not errors. Throws DataError unless both
// trajectories have strictly increasing timestamps.
Association associate(const Trajectory& estimate, const Trajectory& ground_truth,
                      const AssociationOptions& options = {});

}  // namespace orbatlas
