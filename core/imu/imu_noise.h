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

struct ImuNoise {
  double gyro_density = 1.6968e-04;   // rad/s/sqrt(Hz)
  double accel_density = 2.0000e-03;  // m/s^2/sqrt(Hz)
  double gyro_walk = 1.9393e-05;      // rad/s^2/sqrt(Hz)
  double accel_walk = 3.0000e-03;     // m/s^3/sqrt(Hz)

  static ImuNoise from(const ImuCalibration& calibration);

  // Variances of one measurement held over dt (white noise: density^2 / dt).
  double gyro_variance(double dt) const { return gyro_density * gyro_density / dt; }
  double accel_variance(double dt) const { return accel_density * accel_density / dt; }
  // Variances of the bias drift over dt (random walk: density^2 * dt).
  double gyro_walk_variance(double dt) const { return gyro_walk * gyro_walk * dt; }
  double accel_walk_variance(double dt) const { return accel_walk * accel_walk * dt; }

  // Throws Error naming the first value that is not finite and > 0.
  void check() const;
};

}  // namespace orbatlas
