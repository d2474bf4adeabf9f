#pragma once
// Levenberg-Marquardt over one camera pose (6 unknowns) with pose-only cost
// functions, written out instead of handed to ceres::Solve: with a few
// hundred two- or three-row residuals and six unknowns, building a
// ceres::Problem and its evaluators every round cost more than the solve
// (about a fifth of a stereo frame's tracking, perf, 2026-11-26). The same
// algorithm as Ceres's: its trust-region rules (radius 1e4, gain-ratio update,
// doubling decrease), its quaternion manifold, the Huber loss applied as
// iteratively reweighted least squares, and its tolerances.
#include <vector>

#include <ceres/cost_function.h>

#include "core/optimization/pose_parameters.h"

namespace orbatlas {

struct PoseTerm {
  const ceres::CostFunction* cost = nullptr;  // parameter blocks (q 4, t 3), 2 or 3 residuals
  double huber = 0.0;                         // the Huber loss's width; 0: plain squares
};

struct PoseLevenbergOptions {
  int max_iterations = 10;
  double function_tolerance = 1e-12;   // stop when the cost falls by less than this share
  double gradient_tolerance = 1e-14;   // stop when the largest gradient entry is below this
  double parameter_tolerance = 1e-12;  // stop when the step is below this share of the state
};

struct PoseLevenbergResult {
  int iterations = 0;  // steps tried (accepted or not), as Ceres counts them
  double initial_cost = 0.0, final_cost = 0.0;
  bool usable = true;  // false: a residual could not be evaluated at the start (pose unchanged)
};

// Minimises 1/2 sum rho(|r|^2) over `pose` in place.
PoseLevenbergResult solve_pose_levenberg(const std::vector<PoseTerm>& terms, PoseParameters& pose,
                                         const PoseLevenbergOptions& options = {});

}  // namespace orbatlas
