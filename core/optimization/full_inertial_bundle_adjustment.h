#pragma once
// ORB-SLAM3's FullInertialBA, run after a map's inertial initialisation and
// after each refinement: every keyframe and map point of the map, plus the
// IMU velocities and biases of the inertial chain ending at the newest
// keyframe, tied by the preintegrated IMU and the biases' random walk
// (inertial_window.h with the whole chain as the window, no anchor). Gravity
// is the map's (fixed: the initialisation just aligned it); the chain's oldest
// keyframe is fixed for the gauge. Run by the map's local mapping (nothing else
// maps it meanwhile); writes poses, positions and IMU states back, as local BA
// does. Observations are kept (robust kernel); culling is local BA's.
#include <atomic>
#include <cmath>
#include <cstddef>
#include <memory>
#include <vector>

#include "core/camera/camera.h"
#include "core/map/map.h"
#include "core/optimization/chi2.h"
#include "core/optimization/inertial_window.h"
#include "core/optimization/level_sigma.h"

namespace orbatlas {

struct FullInertialBundleAdjustmentOptions {
  int iterations = 20;  // with the Huber kernel (ORB-SLAM3: 100 after the first initialisation)
  double huber_mono = std::sqrt(kChi2Mono95);
  double huber_stereo = std::sqrt(kChi2Stereo95);
  std::vector<double> level_sigma2 = pyramid_level_sigma2();
  // T_b_i, gravity and the biases for keyframes without a state;
  // temporal_keyframes is replaced by the chain's length.
  InertialWindowOptions inertial;
  std::size_t max_chain_keyframes = 200;  // the newest ones of the chain
  int num_threads = 1;

  // Throws Error naming the first value out of range.
  void check() const;
};

struct FullInertialBundleAdjustmentStats {
  std::size_t keyframes = 0, points = 0, observations = 0;
  std::size_t inertial_keyframes = 0, inertial_edges = 0;
  double inertial_chi2_max = 0.0;  // after the solve
  int iterations = 0;
  bool stopped = false;  // interrupted by the stop flag: nothing written
  double time_ms = 0.0;
};

FullInertialBundleAdjustmentStats full_inertial_bundle_adjustment(Map& map, const std::shared_ptr<KeyFrame>& newest,
                                                                  const Camera& camera, double bf,
                                                                  const FullInertialBundleAdjustmentOptions& options,
                                                                  const std::atomic<bool>* stop = nullptr);

}  // namespace orbatlas
