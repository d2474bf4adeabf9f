#include "core/imu/imu_noise.h"

#include <cmath>

#include "core/common/error.h"

namespace orbatlas {

ImuNoise ImuNoise::from(const ImuCalibration& calibration) {
  ImuNoise n;
  n.gyro_density = calibration.gyro_noise_density;
  n.accel_density = calibration.accel_noise_density;
  n.gyro_walk = calibration.gyro_random_walk;
  n.accel_walk = calibration.accel_random_walk;
  n.check();
  return n;
}

void ImuNoise::check() const {
  for (const auto& [name, value] : {std::pair{"IMU.NoiseGyro", gyro_density}, std::pair{"IMU.NoiseAcc", accel_density},
                                    std::pair{"IMU.GyroWalk", gyro_walk}, std::pair{"IMU.AccWalk", accel_walk}})
    ORBATLAS_CHECK(std::isfinite(value) && value > 0.0,
                   "imu: " << name << " must be a finite value > 0, not " << value);
  ORBATLAS_CHECK(vibration.rotation_var.allFinite() && vibration.rotation_var.minCoeff() >= 0.0 &&
                     vibration.velocity_var.allFinite() && vibration.velocity_var.minCoeff() >= 0.0,
                 "imu: the vibration's variances must be finite and >= 0");
}

}  // namespace orbatlas
