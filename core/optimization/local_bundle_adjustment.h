#pragma once
// ORB-SLAM's LocalBundleAdjustment on the map model: the current keyframe and its
// covisible keyframes (the window) and every map point they observe are
// optimised; the other keyframes observing those points are fixed (the border).
// Visual-inertial maps add ORB-SLAM3's LocalInertialBA: the last keyframes of
// the inertial chain join the window with their velocities and biases.
// Two stages (5 robust + 10 plain iterations); afterwards, observations with a
// chi2 above the threshold or a point behind the camera are erased from the map,
// and the poses and points are written back. See docs/optimization.md.
#include <atomic>
#include <cmath>
#include <cstddef>
#include <limits>
#include <memory>
#include <optional>
#include <vector>

#include "core/camera/camera.h"
#include "core/map/map.h"
#include "core/optimization/chi2.h"
#include "core/optimization/inertial_window.h"
#include "core/optimization/level_sigma.h"

namespace orbatlas {

struct LocalBundleAdjustmentOptions {
  // Window: the current keyframe and at most this many of its best covisibles
  // (by weight); ORB-SLAM takes all of them.
  std::size_t max_covisibles = std::numeric_limits<std::size_t>::max();
  int first_iterations = 5;    // with the Huber kernel, on all observations
  int second_iterations = 10;  // without kernel, outliers of the first stage left out (0: skip)
  double chi2_mono = kChi2Mono95;
  double chi2_stereo = kChi2Stereo95;
  double huber_mono = std::sqrt(kChi2Mono95);
  double huber_stereo = std::sqrt(kChi2Stereo95);
  std::vector<double> level_sigma2 = pyramid_level_sigma2();  // per pyramid level
  // Kept fixed when it is in the window (the map's first keyframe, as ORB-SLAM).
  std::optional<KeyframeId> origin;
  // Gauge: when no keyframe would be fixed, fix the oldest one of the window.
  bool fix_oldest_without_border = true;
  // The own solver, or Ceres' DENSE_SCHUR, up to this many free keyframes;
  // Ceres' SPARSE_SCHUR above. The reduced system of a local window (6
  // unknowns a keyframe, 9 more for each of the inertial chain's) is small
  // enough for dense: a visual-inertial window on real MH_01 holds up to 138,
  // and at 200 instead of 100 its local mapping's p95 went from 3.3 s to 1.0 s
  // a keyframe with the same trajectory (docs/benchmarks.md).
  std::size_t dense_schur_max_keyframes = 200;
  // Up to dense_schur_max_keyframes free keyframes (inertial terms included),
  // solve with orbatlas' own Levenberg-Marquardt (bundle_levenberg.h), the
  // same algorithm as Ceres' written for this problem; false: Ceres.
  bool own_solver = true;
  // After erasing observations, points left with fewer observers are culled
  // from the map (ORB-SLAM discards them in EraseObservation); 0 never culls.
  std::size_t min_observers = 2;
  int num_threads = 1;
  // Visual-inertial (an initialised map's keyframes linked by the IMU): the
  // temporal window along the inertial chain joins the window, with its IMU
  // velocities and biases (inertial_window.h); none: visual only.
  std::optional<InertialWindowOptions> inertial;

  // Throws Error naming the first value out of range.
  void check() const;
};

struct LocalBundleAdjustmentStats {
  std::size_t window_keyframes = 0;  // optimised
  std::size_t fixed_keyframes = 0;   // border (+ origin / gauge keyframe)
  std::size_t points = 0;
  std::size_t observations = 0;          // residuals built
  std::size_t observations_removed = 0;  // erased from the map
  std::size_t points_culled = 0;
  std::size_t inertial_keyframes = 0;  // with IMU velocity and biases (the anchor included)
  std::size_t inertial_edges = 0;
  double inertial_chi2_max = 0.0;  // of the inertial edges after the solve (infinite: not evaluable)
  double inertial_chi2_median = 0.0;
  ImuScaleCorrection imu_scale;  // the window's IMU scale correction as solved (InertialWindowOptions::scale_sigma)
  ImuScaleInformation imu_scale_information = ImuScaleInformation::Zero();  // what the window told of it
  int iterations = 0;                                                       // both stages
  bool stopped = false;                                                     // interrupted by the stop flag
  double time_ms = 0.0;
};

// `camera`: the model of every keyframe's (left) keypoints; `bf`: baseline * fx of
// the rectified stereo pair (stereo observations, i.e. u_right >= 0, count as
// monocular when bf <= 0). `stop` (may be null) is polled at every iteration;
// when raised the solve ends early, the current estimates are written back and
// no observation is erased. Throws Error on a keypoint level without sigma2.
LocalBundleAdjustmentStats local_bundle_adjustment(Map& map, const std::shared_ptr<KeyFrame>& current,
                                                   const Camera& camera, double bf,
                                                   const LocalBundleAdjustmentOptions& options = {},
                                                   const std::atomic<bool>* stop = nullptr);

}  // namespace orbatlas
