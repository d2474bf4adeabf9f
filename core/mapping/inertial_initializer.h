#pragma once
// When a visual-inertial map is initialised (ORB-SLAM3's LocalMapping::
// InitializeIMU, first stage): once the inertial chain of keyframes reaching
// the newest one spans about 2 s, the inertial-only MAP estimate
// (core/imu/inertial_initialization.h) gives the map its gravity and IMU biases.
// Run by local mapping after a keyframe; what it finds is the map's
// InertialState (stats: imu_initialized_at_s, imu_bias), and the map is turned
// so that gravity points along -z of its frame (its yaw is kept); refined at 5,
// 15 s and every 10 s from 25 to 75 s (refine_map_inertial).
#include <memory>
#include <optional>

#include "core/geometry/pose.h"
#include "core/imu/inertial_initialization.h"
#include "core/map/atlas.h"
#include "core/map/inertial_chain.h"
#include "core/map/map.h"

namespace orbatlas {

// A refinement of an initialised map (ORB-SLAM3's InitializeIMU again, 5 s
// and 15 s after the first; then, as ORB-SLAM3 refines a monocular map's
// gravity, every 10 s from 25 to 75 s): the inertial-only estimate over the
// chain with the biases' priors relaxed, the map turned to the gravity it finds.
// The later ones free a horizontal accelerometer bias from a tilt of gravity,
// which only a turn about gravity tells apart (docs/inertial.md).
struct InertialRefinement {
  double after_s = 0.0;  // after the initialisation
  double gyro_bias_prior = 0.0, accel_bias_prior = 0.0;
};

struct InertialInitializationOptions {
  bool enabled = false;  // the session fuses an IMU (its keyframes carry inertial links)
  Pose3 T_b_i;           // the IMU in the body frame (the settings')
  double after_s = 2.0;  // span of the chain needed
  // Keyframes needed in the chain (ORB-SLAM3: 10; a stereo map here makes fewer
  // keyframes in its first seconds, each seeing its points in depth).
  std::size_t min_keyframes = 5;
  InertialInitOptions solver;
  // ORB-SLAM3's: at 5 s with priors 1 and 1e5, at 15 s with none; then every
  // 10 s to 75 s with none.
  std::vector<InertialRefinement> refinements = {{5.0, 1.0, 1e5},  {15.0, 0.0, 0.0}, {25.0, 0.0, 0.0},
                                                 {35.0, 0.0, 0.0}, {45.0, 0.0, 0.0}, {55.0, 0.0, 0.0},
                                                 {65.0, 0.0, 0.0}, {75.0, 0.0, 0.0}};
  std::size_t refinement_max_keyframes = 200;  // the newest ones of the chain
  // A refinement runs only on a chain spanning at least this fraction of the
  // window the map's estimate came from (InertialState::span_s): after a merge
  // or a late join the session's chain is a few seconds long, and its gravity
  // and scale would be applied to the whole map. Tried once all the same.
  double refinement_min_span_fraction = 0.8;
  // A refinement of a metric map (stereo, RGB-D) that would free the
  // accelerometer bias (its prior below `held_accel_bias_prior`) keeps it held
  // under that prior while the chain has turned about gravity by less than
  // this: until the rig turns, a horizontal bias and a tilt of gravity are one
  // measurement, and the free estimate splits them by the noise (real-look MH_03, 11 degrees in its first 18 s: the
  // 15-s refinement found a bias 0.17 m/s^2 off and tilted the map 1.6 degrees).
  double min_turn_to_free_accel_bias_deg = 45.0;
  double held_accel_bias_prior = 1e5;  // the 5-s refinement's
  // A link whose linearisation gyro bias is this far from the bias found is
  // integrated again at it (ORB-SLAM3's 0.01 rad/s): the rotation increment
  // is corrected to first order only, which a larger change leaves off.
  double reintegrate_gyro_bias_change = 0.01;
  // An estimate is kept only when it is plausible (else the initialisation is
  // retried at a later keyframe, a refinement leaves the map as it was): biases
  // of at most these norms (a MEMS IMU's are a few hundredths; EuRoC's 0.08
  // rad/s and 0.15 m/s^2); the chain's rotation residuals with a median chi2 of
  // at most this (3 degrees of freedom: the gyro agrees with the visual
  // rotation within what its noise, vibration included, allows), and once the
  // accelerometer bias is free (its prior at most 1: the refinements from the
  // second on) the whole inertial residuals' (9 degrees of freedom) too; a
  // refinement turning the map's gravity by at most this.
  double max_gyro_bias = 0.5;             // rad/s
  double max_accel_bias = 1.0;            // m/s^2
  double max_median_rotation_chi2 = 9.0;  // 3 x the degrees of freedom
  double max_median_link_chi2 = 27.0;     // 3 x the degrees of freedom
  double max_refinement_turn_deg = 2.0;

  // Throws Error naming the first value out of range.
  void check() const;
};

// Initialises `map` when it is not yet and the chain ending at `newest` is long
// enough, and aligns it with gravity (Map::change_frame, under `atlas`'s maps
// held exclusive when `atlas` is given; the caller is the map's local mapping,
// so nothing else maps it meanwhile); returns the state it set.
std::optional<Map::InertialState> initialize_map_inertial(Map& map, const std::shared_ptr<KeyFrame>& newest,
                                                          const InertialInitializationOptions& options,
                                                          Atlas* atlas = nullptr);

// The next refinement of an initialised map when its time has come (the chain
// ending at `newest` estimated again, each of its keyframes given the velocity
// and biases found, the map turned to the gravity found); returns the state it
// set. A refinement is tried once (Map::InertialState::refinements counts them),
// and skipped when the chain is too short (refinement_min_span_fraction).
std::optional<Map::InertialState> refine_map_inertial(Map& map, const std::shared_ptr<KeyFrame>& newest,
                                                      const InertialInitializationOptions& options,
                                                      Atlas* atlas = nullptr);

}  // namespace orbatlas
