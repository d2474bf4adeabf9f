#pragma once
// Trajectory error metrics on associated pose pairs: the absolute trajectory error
// (ATE, positions after alignment) and the relative pose error (RPE, motion over a
// fixed time delta).
#include <cstddef>
#include <vector>

#include "core/eval/alignment.h"
#include "core/eval/association.h"

namespace orbatlas {

struct ErrorStats {
  double rmse = 0, mean = 0, median = 0, max = 0;
  std::size_t count = 0;
};

// Statistics of a list of non-negative errors; all zero when it is empty.
ErrorStats error_stats(std::vector<double> errors);

// |gt position - aligned estimated position| for every pair.
std::vector<double> ate_errors(const std::vector<PosePair>& pairs, const Similarity3& alignment);

struct RpeStats {
  double trans_rmse_m = 0;  // translation part of the relative-motion error
  double rot_rmse_deg = 0;  // rotation angle of the relative-motion error
  std::size_t pairs = 0;    // number of (i, j) pose pairs used
};

// Relative motions over delta: for each pair i, j is the first pair with
// t_j >= t_i + delta, used if t_j - t_i <= 1.5 delta (a tracking gap otherwise).
// Error of a relative motion: (gt_i^-1 gt_j)^-1 (est_i^-1 est_j), its estimated
// translation multiplied by `scale` (the sim3 scale; 1 otherwise). Rigid
// alignments cancel out. With no usable pair every value is 0 and pairs is 0.
RpeStats relative_pose_error(const std::vector<PosePair>& pairs, double scale, TimestampNs delta_ns);

}  // namespace orbatlas
