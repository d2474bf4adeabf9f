#pragma once
// Levenberg-Marquardt for a bundle adjustment (keyframe poses and map points
// with reprojection residuals, and the extra terms of a visual-inertial window:
// inertial edges, bias walks, priors over poses, velocities and biases),
// written out instead of handed to ceres::Solve. A local BA is the mapping
// thread's largest cost and, when tracking waits for its keyframe's BA
// (Orbatlas.Tracker.MaxMappingWaitMs), a frame's latency. Ceres spends its
// time there in generic machinery: a problem and a reduced program built per
// stage, per-block bookkeeping in its Schur eliminator with the pose split
// into two 3-blocks (and locks per cell of the reduced matrix), the manifold's
// Jacobian applied per residual block (perf on MH_04 and MH_01,
// docs/benchmarks.md).
//
// The algorithm is Ceres' (as pose_levenberg.h for one pose): the same trust
// region rules (gain-ratio update, doubling decrease; the damping is the
// clamped diagonal of J^T W J over the radius, what Ceres' Jacobi scaling
// amounts to), the Huber kernel as Ceres applies it (a weight, its second
// derivative being negative), the quaternion manifold, the tolerances. Points
// are eliminated exactly (Schur complement on 3x3 blocks); the reduced system
// over the free poses (6 unknowns each) and the extra terms' free blocks
// (velocities, biases) is dense and solved by Cholesky: for a local window. The
// extra terms are Ceres cost functions, evaluated through their interface.
#include <atomic>

#include "core/optimization/bundle_problem.h"

namespace orbatlas {

struct BundleLevenbergOptions {
  int max_iterations = 10;
  double function_tolerance = 1e-12;        // stop when the cost falls by less than this share
  double gradient_tolerance = 1e-14;        // stop when the largest gradient entry is below this
  double parameter_tolerance = 1e-12;       // stop when the step is below this share of the state
  double initial_radius = 1e4;              // BundleSettings::inertial_trust_region_radius with extra terms
  const std::atomic<bool>* stop = nullptr;  // polled before each iteration; null: never stops
};

struct BundleLevenbergResult {
  int iterations = 0;  // steps tried (accepted or not), as Ceres counts them
  double initial_cost = 0.0, final_cost = 0.0;
  bool usable = true;    // false: an observation could not be evaluated at the start (nothing changed)
  bool stopped = false;  // the stop flag ended it (the last accepted iterate is kept)
};

// Minimises 1/2 sum rho(|r|^2) over the active edges of `problem`, in place:
// the poses of the keyframes that are not fixed and the points those edges
// observe, and the free extra blocks of the extra terms. `robust`: the Huber
// kernel of settings.huber_mono / huber_stereo on each edge (an extra term has
// its own, BundleExtraTerm::huber, in every stage). Throws Error when an extra
// term's block is neither a keyframe's pose nor one of the problem's extra
// blocks.
BundleLevenbergResult solve_bundle_levenberg(BundleProblem& problem, bool robust, const BundleSettings& settings,
                                             const BundleLevenbergOptions& options);

}  // namespace orbatlas
