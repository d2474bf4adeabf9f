#pragma once
// Synthetic IMU from a smooth trajectory: body angular rate and specific force
// (acceleration minus gravity, in the IMU frame) plus white noise and bias random
// walks with the given densities (continuous-time, discretised at the IMU rate).
#include <cstdint>
#include <vector>

#include "core/io/euroc_types.h"
#include "core/sim/trajectory_spline.h"

namespace orbatlas::sim {

constexpr double kGravity = 9.81;  // m/s^2, along -z of the world

struct ImuSynthesisOptions {
  ImuCalibration calibration;  // rate, noise densities, T_b_i
  bool add_noise = true;
  std::uint64_t seed = 1;
  // Initial biases are drawn from N(0, sigma^2) per axis (EuRoC-like magnitudes).
  double initial_gyro_bias_sigma = 0.01;   // rad/s
  double initial_accel_bias_sigma = 0.05;  // m/s^2
  // Vibration of the airframe (the real look): three sinusoids per sensor at
  // rotor-like frequencies (aliased by the IMU rate), random axes and phases,
  // with these amplitudes (0: none).
  double vibration_accel = 0.0;  // m/s^2
  double vibration_gyro = 0.0;   // rad/s

  // Throws Error naming the first value out of range.
  void check() const;
};

struct SyntheticImu {
  std::vector<ImuSample> samples;
  std::vector<GroundTruthState> states;  // true state (pose, velocity, biases) at each sample time
};

// Samples on the grid first_ns + k * period while inside the spline.
SyntheticImu synthesize_imu(const TrajectorySpline& trajectory, TimestampNs first_ns, TimestampNs last_ns,
                            const ImuSynthesisOptions& options);

// The ideal measurement (no noise, no bias) of an IMU at T_b_i on the body.
ImuSample ideal_imu_sample(const TrajectorySpline& trajectory, TimestampNs t, const Pose3& T_b_i);
ImuSample ideal_imu_from_state(const SplineState& state, TimestampNs t, const Pose3& T_b_i);

}  // namespace orbatlas::sim
