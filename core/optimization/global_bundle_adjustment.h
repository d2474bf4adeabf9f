#pragma once
// ORB-SLAM's global bundle adjustment after a loop closure: every keyframe and
// map point of a map, one keyframe fixed for the gauge, robust kernel. It runs
// in the background while tracking and local mapping go on, so it does not
// write into the map: it returns the optimised poses and positions together with
// the keyframe poses it started from, and the caller merges them into the map
// (with the keyframes and points created meanwhile) while mapping is paused.
#include <Eigen/Core>
#include <atomic>
#include <cmath>
#include <optional>
#include <unordered_map>

#include "core/camera/camera.h"
#include "core/geometry/pose.h"
#include "core/map/map.h"
#include "core/optimization/chi2.h"
#include "core/optimization/level_sigma.h"

namespace orbatlas {

struct GlobalBundleAdjustmentOptions {
  int iterations = 10;  // with the Huber kernel, as ORB-SLAM's RunGlobalBundleAdjustment
  double huber_mono = std::sqrt(kChi2Mono95);
  double huber_stereo = std::sqrt(kChi2Stereo95);
  std::vector<double> level_sigma2 = pyramid_level_sigma2();
  // Fixed for the gauge; by default the map's oldest live keyframe.
  std::optional<KeyframeId> origin;
  int num_threads = 1;
  // Visual-inertial sessions (each chain's IMU placed by its links' T_c_i; T_b_i,
  // the IMU in the body, for links without it): when the map is
  // inertially initialised, each of its inertial chains (one per session that
  // mapped in it; the newest max_chain_keyframes of each) joins with its IMU
  // velocities and biases, tied by the preintegrated IMU and the biases' random walk, in
  // the map's gravity (ORB-SLAM3's FullInertialBA). None: visual only.
  // The inertial terms get a Huber kernel at the 95 % quantile of their chi2:
  // over a whole map, links the IMU and the images disagree on (a real IMU
  // beside the rendered motion: chi2 up to 330) would otherwise bend every
  // keyframe towards them; a consistent map's (chi2 under 13) are untouched.
  struct Inertial {
    Pose3 T_b_i;
    std::size_t max_chain_keyframes = 200;
    double huber = std::sqrt(kChi2Inertial95);  // 0: none
  };
  std::optional<Inertial> inertial;

  // Throws Error naming the first value out of range.
  void check() const;
};

struct GlobalBundleAdjustmentResult {
  std::unordered_map<KeyframeId, Pose3> T_w_b_before;   // body poses the solve started from
  std::unordered_map<KeyframeId, Pose3> T_w_b;          // optimised body poses
  std::unordered_map<MapPointId, Eigen::Vector3d> p_w;  // optimised positions
  // Optimised IMU states of the inertial chain (velocity in the IMU frame of the
  // optimised pose), when inertial terms joined.
  std::unordered_map<KeyframeId, KeyFrame::ImuState> imu_states;
  std::size_t inertial_chains = 0, inertial_keyframes = 0, inertial_edges = 0;
  double inertial_chi2_max = 0.0;  // after the solve
  std::size_t keyframes = 0, points = 0, observations = 0;
  int iterations = 0;
  bool stopped = false;           // interrupted by the stop flag: the result should be dropped
  std::uint64_t frame_epoch = 0;  // the map's frame when solved (Map::frame_epoch)
  double time_ms = 0.0;
};

// Reads `map` through its snapshots (other threads may edit it meanwhile).
// `stop` (may be null) is polled at every iteration.
// `options` with the sigmas of the camera's own pyramid (the defaults are ORB-SLAM's
// 8 levels of 1.2; a camera with other settings weights its observations by these).
inline GlobalBundleAdjustmentOptions with_level_sigma2(GlobalBundleAdjustmentOptions options,
                                                       std::vector<double> level_sigma2) {
  options.level_sigma2 = std::move(level_sigma2);
  return options;
}

GlobalBundleAdjustmentResult global_bundle_adjustment(const Map& map, const Camera& camera, double bf,
                                                      const GlobalBundleAdjustmentOptions& options = {},
                                                      const std::atomic<bool>* stop = nullptr);

}  // namespace orbatlas
