#pragma once
// What a multirotor's IMU measures of its own motors: broadband vibration while
// they run, none while the airframe is parked. The spectrum is the one measured
// in the real EuRoC flights (scripts/analysis/imu_spectrum.py prints it from the real
// recordings); the motors' schedule comes from the trajectory itself (parked
// on the floor before take-off, see motor_schedule()). docs/simulator.md.
#include <Eigen/Core>
#include <cstddef>
#include <random>
#include <vector>

#include "core/common/timestamp.h"
#include "core/sim/trajectory_spline.h"

namespace orbatlas::sim {

// A one-sided amplitude spectral density (the square root of the power
// spectral density) per axis, constant over bands of `band_hz` from `first_hz`
// on; zero outside the bands.
struct VibrationSpectrum {
  double first_hz = 5.0;
  double band_hz = 5.0;
  std::vector<Eigen::Vector3d> gyro;   // rad/s/sqrt(Hz), one per band
  std::vector<Eigen::Vector3d> accel;  // m/s^2/sqrt(Hz), one per band

  // Root mean square per axis of the gyro (or accelerometer) vibration up to
  // `nyquist_hz`: sqrt(sum of density^2 * band width).
  Eigen::Vector3d gyro_rms(double nyquist_hz) const;
  Eigen::Vector3d accel_rms(double nyquist_hz) const;
};

// The real MH_05 flight (40-100 s of its IMU, 5 Hz bands from 5 to 100 Hz; the
// real MH_01 flight gives the same within about 15 % per band). Below 5 Hz the
// real IMU measures the flight's own motion, which the trajectory carries.
const VibrationSpectrum& euroc_flight_vibration();

// Gaussian noise with the one-sided amplitude spectral density `density`
// (per axis, one entry per band as in VibrationSpectrum), `count` samples at
// `rate_hz` (shaped in the frequency domain).
std::vector<Eigen::Vector3d> shaped_noise(const std::vector<Eigen::Vector3d>& density, double first_hz, double band_hz,
                                          std::size_t count, double rate_hz, std::mt19937_64& rng);

// When the motors run, from the trajectory: an EuRoC flight starts hand-held,
// is set down on the floor and parked (still for seconds), and takes off; it
// may land at the end. Take-off is the end of the last still stretch (speed
// under 5 cm/s for at least 2 s) that starts in the first half of the
// trajectory; the motors idle for `idle_s` before it (the real MH_05 and MH_01
// IMUs show a third of the flight's vibration then) and run until a still
// stretch in the second half (landing). No such stretch: flying throughout.
struct MotorSchedule {
  TimestampNs idle_from_ns = 0;
  TimestampNs takeoff_ns = 0;
  TimestampNs landing_ns = 0;  // motors off from here on
  double idle_level = 0.35;    // vibration while idling, relative to flight

  // The vibration's level at t: 0 parked, idle_level idling, 1 flying (ramps
  // of 1 s between them).
  double level(TimestampNs t) const;
};
MotorSchedule motor_schedule(const TrajectorySpline& trajectory, double idle_s = 5.0);

}  // namespace orbatlas::sim
