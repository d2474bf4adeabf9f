#pragma once
// Synthetic IMU from a smooth trajectory: body angular rate and specific force
// (acceleration minus gravity, in the IMU frame) plus what a real IMU adds to
// them (ImuErrorModel): white noise and bias random walks, biases, vibration,
// scale errors, a mounting that differs from the calibration and a clock
// offset from the cameras'.
#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "core/io/euroc_types.h"
#include "core/sim/trajectory_spline.h"

namespace orbatlas::sim {

constexpr double kGravity = 9.81;  // m/s^2, along -z of the world

// How the synthesised IMU differs from the ideal one. ideal_imu_errors() is
// the clean look's (noise of exactly the calibration's densities, small
// biases, nothing else); realistic_imu_errors() the real look's, taken from
// the real EuRoC recordings (docs/simulator.md, "The IMU").
struct ImuErrorModel {
  // Densities of the white noise and the bias random walks synthesised; a
  // negative value: the calibration's (what the estimator is told).
  double gyro_noise_density = -1.0;   // rad/s/sqrt(Hz)
  double accel_noise_density = -1.0;  // m/s^2/sqrt(Hz)
  double gyro_random_walk = -1.0;     // rad/s^2/sqrt(Hz)
  double accel_random_walk = -1.0;    // m/s^3/sqrt(Hz)
  // Initial biases drawn per axis from N(mean, sigma^2).
  Eigen::Vector3d gyro_bias_mean = Eigen::Vector3d::Zero();
  Eigen::Vector3d gyro_bias_sigma = Eigen::Vector3d::Constant(0.01);  // rad/s
  Eigen::Vector3d accel_bias_mean = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel_bias_sigma = Eigen::Vector3d::Constant(0.05);  // m/s^2
  // Scale of the real flights' vibration (euroc_flight_vibration(), while the
  // motors run: motor_schedule()); 0: none.
  double vibration = 0.0;
  // Each axis' scale factor is 1 + N(0, scale_error^2) (gyro and accelerometer).
  double scale_error = 0.0;
  // The IMU's true mounting differs from the calibration's T_b_i by a rotation
  // of N(0, sigma^2) degrees and a translation of N(0, sigma^2) m per axis.
  double extrinsic_rotation_deg = 0.0;
  double extrinsic_translation_m = 0.0;
  // The IMU's clock is late by this against the cameras': the sample stamped t
  // measured the motion at camera time t - time_offset_s.
  double time_offset_s = 0.0;

  // Throws Error naming the first value out of range.
  void check() const;
};

// The clean look's IMU: the calibration's noise, biases from N(0, 0.01 rad/s)
// and N(0, 0.05 m/s^2), no vibration, exact mounting and clock.
ImuErrorModel ideal_imu_errors();
// The real look's IMU: the real EuRoC IMU's noise (measured while parked),
// biases around the real device's, the real flights' vibration while the motors
// run, scale errors of 0.2 % and a mounting 0.05 deg and 1 mm off (per axis);
// no clock offset (an option).
ImuErrorModel realistic_imu_errors();

struct ImuSynthesisOptions {
  ImuCalibration calibration;  // rate, noise densities, T_b_i (what is written and told)
  bool add_noise = true;       // false: the ideal measurement, whatever `errors` says
  std::uint64_t seed = 1;
  ImuErrorModel errors = ideal_imu_errors();

  // Throws Error naming the first value out of range.
  void check() const;
};

struct SyntheticImu {
  std::vector<ImuSample> samples;
  std::vector<GroundTruthState> states;  // true state (pose, velocity, biases) at each sample's stamp
  Pose3 true_T_b_i;                      // the mounting the samples were synthesised at
  Eigen::Vector3d gyro_scale = Eigen::Vector3d::Ones(), accel_scale = Eigen::Vector3d::Ones();
};

// Samples stamped on the grid first_ns + k * period while the trajectory covers
// what they measured.
SyntheticImu synthesize_imu(const TrajectorySpline& trajectory, TimestampNs first_ns, TimestampNs last_ns,
                            const ImuSynthesisOptions& options);

// The ideal measurement (no noise, no bias) of an IMU at T_b_i on the body.
ImuSample ideal_imu_sample(const TrajectorySpline& trajectory, TimestampNs t, const Pose3& T_b_i);
ImuSample ideal_imu_from_state(const SplineState& state, TimestampNs t, const Pose3& T_b_i);

}  // namespace orbatlas::sim
