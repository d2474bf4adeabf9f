#pragma once
// The bundle-adjustment problem shared by local and global bundle adjustment
// (internal to orbatlas_optimization): a set of keyframes to optimise (the
// window), the other keyframes observing the window's points (fixed: the
// border), the points and their observations, with the Ceres parameter storage
// (never resized once built: Ceres keeps pointers into it).
#include <ceres/cost_function.h>
#include <ceres/solver.h>

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "core/camera/camera.h"
#include "core/map/keyframe.h"
#include "core/map/map_point.h"
#include "core/optimization/pose_parameters.h"
#include "core/optimization/stop_flag_callback.h"

namespace orbatlas {

struct BundleSettings {
  double chi2_mono = 0.0, chi2_stereo = 0.0;    // outlier thresholds
  double huber_mono = 0.0, huber_stereo = 0.0;  // robust kernel widths
  std::vector<double> level_sigma2;             // per pyramid level
  std::size_t dense_schur_max_keyframes = 40;   // DENSE_SCHUR up to this many free keyframes
  // Up to dense_schur_max_keyframes free keyframes, a problem (observations and
  // any extra terms) is solved by solve_bundle_levenberg (bundle_levenberg.h)
  // instead of Ceres.
  bool own_solver = false;
  int num_threads = 1;
  // Levenberg-Marquardt's first trust region with inertial terms: Ceres'
  // default (1e4) lets the first steps throw weakly observed points through a
  // camera (evaluation failures, a rejected step in every other iteration on
  // MH_01); 1e2 measured one rejected step in 50 BAs, 1 damped the solve too much.
  double inertial_trust_region_radius = 1e2;
};

struct BundleEdge {
  std::size_t keyframe = 0;  // index into BundleProblem::keyframes
  std::size_t point = 0;     // index into BundleProblem::points
  std::size_t slot = 0;
  bool stereo = false;
  bool active = true;  // in the next stage's problem
  std::unique_ptr<ceres::CostFunction> cost;
};

// A parameter block besides poses and points (visual-inertial BA: a
// keyframe's IMU velocity or biases), at a stable address.
struct BundleExtraBlock {
  std::unique_ptr<double[]> values;
  int size = 0;
  bool fixed = false;
};

// A residual besides the observations, over keyframe poses and extra blocks
// (an inertial edge, a bias random walk); in every stage, without a kernel.
struct BundleExtraTerm {
  std::unique_ptr<ceres::CostFunction> cost;
  std::vector<double*> blocks;         // in the cost's order
  std::vector<std::size_t> keyframes;  // whose pose blocks are among `blocks`
  double huber = 0.0;                  // > 0: a Huber kernel of this width on the whitened residual
};

struct BundleProblem {
  std::vector<std::shared_ptr<KeyFrame>> keyframes;  // window first, then the border
  std::vector<std::uint8_t> fixed;                   // per keyframe
  std::size_t window = 0;
  std::vector<PoseParameters> poses;  // T_c_w per keyframe
  std::vector<std::shared_ptr<MapPoint>> points;
  std::vector<std::array<double, 3>> positions;
  std::vector<BundleEdge> edges;
  std::vector<BundleExtraBlock> extra_blocks;
  std::vector<BundleExtraTerm> extra_terms;

  std::array<const double*, 3> parameters(const BundleEdge& e) const {
    return {poses[e.keyframe].q.data(), poses[e.keyframe].t.data(), positions[e.point].data()};
  }
};

// The window's keyframes (live, distinct), every point they observe, and every
// observation of those points; observers outside the window join as fixed
// border keyframes. Only the border is fixed: the caller fixes gauge keyframes.
// Throws Error on a keypoint level without a sigma2.
BundleProblem collect_bundle_problem(const std::vector<std::shared_ptr<KeyFrame>>& window, const Camera& camera,
                                     double bf, const BundleSettings& settings);

// The index of `kf` in the problem; a keyframe not yet in it joins as a fixed
// border keyframe (before the first stage is solved).
std::size_t bundle_keyframe_index(BundleProblem& problem, const std::shared_ptr<KeyFrame>& kf);

// Chi2 at the current estimates; nullopt when the point is behind the camera or
// cannot be projected.
std::optional<double> bundle_edge_chi2(const BundleProblem& problem, const BundleEdge& e);
bool is_bundle_outlier(const BundleProblem& problem, const BundleEdge& e, const BundleSettings& settings);

// One stage: a problem over the active edges, solved for at most `iterations`
// iterations; returns the iterations run (as Ceres counts them). An edge that
// cannot be evaluated where the stage starts is made inactive and the stage
// solved again without it.
int solve_bundle_stage(BundleProblem& problem, bool robust, int iterations, const BundleSettings& settings,
                       StopFlagCallback& callback);

}  // namespace orbatlas
