#pragma once
// An IMU's biases and noise: the continuous-time densities of the settings
// (IMU.NoiseGyro, IMU.NoiseAcc, IMU.GyroWalk, IMU.AccWalk) and what they mean
// for a measurement held over dt seconds.
#include <Eigen/Core>

#include "core/io/euroc_types.h"

namespace orbatlas {

struct ImuBias {
  Eigen::Vector3d gyro = Eigen::Vector3d::Zero();   // rad/s
  Eigen::Vector3d accel = Eigen::Vector3d::Zero();  // m/s^2

  bool operator==(const ImuBias&) const = default;
};

// A correction of the IMU's scale factors, per axis: the angular rate and the
// specific force are (1 + gyro) and (1 + accel) times the measurement less its
// bias. A MEMS IMU's factors are off by a few tenths of a percent; the
// accelerometer's then scale the motion the IMU reports against the stereo's.
struct ImuScaleCorrection {
  Eigen::Vector3d gyro = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel = Eigen::Vector3d::Zero();

  bool operator==(const ImuScaleCorrection&) const = default;
};

// What vibration adds at each end of an interval to the error of the
// integrated rotation and velocity, per axis of the IMU frame (variances, rad^2
// and (m/s)^2; core/imu/vibration_estimate.h measures it).
struct ImuVibration {
  Eigen::Vector3d rotation_var = Eigen::Vector3d::Zero();
  Eigen::Vector3d velocity_var = Eigen::Vector3d::Zero();

  bool operator==(const ImuVibration&) const = default;
};

struct ImuNoise {
  double gyro_density = 1.6968e-04;   // rad/s/sqrt(Hz)
  double accel_density = 2.0000e-03;  // m/s^2/sqrt(Hz)
  double gyro_walk = 1.9393e-05;      // rad/s^2/sqrt(Hz)
  double accel_walk = 3.0000e-03;     // m/s^3/sqrt(Hz)
  ImuVibration vibration;             // zero: the densities alone (an IMU without vibration)

  static ImuNoise from(const ImuCalibration& calibration);

  // Variances of one measurement held over dt (white noise: density^2 / dt).
  double gyro_variance(double dt) const { return gyro_density * gyro_density / dt; }
  double accel_variance(double dt) const { return accel_density * accel_density / dt; }
  // Variances of the bias drift over dt (random walk: density^2 * dt).
  double gyro_walk_variance(double dt) const { return gyro_walk * gyro_walk * dt; }
  double accel_walk_variance(double dt) const { return accel_walk * accel_walk * dt; }

  // Throws Error naming the first value that is not finite and > 0 (the
  // vibration's: finite and >= 0).
  void check() const;
};

}  // namespace orbatlas
