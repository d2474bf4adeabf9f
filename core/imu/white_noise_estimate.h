#pragma once
// The white noise an IMU's samples show: a real IMU's is often above its
// datasheet's densities, and increments preintegrated with too little noise
// get residuals the consistency check cannot tell from a wrong inertial state.
// The real look's IMU has 1.6 and 2.25 times the settings' gyroscope and
// accelerometer densities; the real MH_05 recording before take-off the
// settings' gyroscope density and 1.6-2.0 times the accelerometer's.
//
// Measured from the samples' second differences over the last `window_s`: a
// sixth of their variance is the white noise's variance per sample
// (density^2 / dt). The rig's own motion is smooth at the sampling rate and
// adds little to them (first differences of the MH_05 recording's hand-held
// start read up to 2.8 times the gyroscope density, second ones 1.05). The variance is taken robustly (the mean of the
// lowest 90 % of the squares, scaled for Gaussian values), per axis, and
// averaged over the three axes: that keeps a residual's chi2 at its degrees
// of freedom on average.
//
// Vibration adds far more to the differences (the real flights': 15-35 times
// the settings' densities), and it is not white: its error does not grow with
// the interval (vibration_estimate.h covers it). So what is counted as white
// noise is at most `max_factor` times the settings' densities, and never
// below them.
#include <optional>
#include <vector>

#include "core/common/timestamp.h"
#include "core/imu/imu_noise.h"
#include "core/io/euroc_types.h"

namespace orbatlas {

struct WhiteNoiseEstimateOptions {
  double window_s = 2.0;  // measured over this long before the time asked for
  // The densities used are at most this many times the settings'.
  double max_factor = 3.0;

  // Throws Error naming the first value out of range.
  void check() const;
};

// White-noise densities, rad/s/sqrt(Hz) and m/s^2/sqrt(Hz).
struct WhiteNoiseDensities {
  double gyro = 0.0;
  double accel = 0.0;
};

// The densities measured in the samples up to `t_ns`; none when they do not
// cover window_s (fewer than 50 samples) or have a gap over 50 ms in it.
std::optional<WhiteNoiseDensities> measure_white_noise(const std::vector<ImuSample>& samples, TimestampNs t_ns,
                                                       const WhiteNoiseEstimateOptions& options = {});

// `settings` with its white-noise densities raised to those measured up to
// `t_ns`, within [1, max_factor] times the settings' (`settings` unchanged
// when nothing could be measured).
ImuNoise with_measured_white_noise(const std::vector<ImuSample>& samples, TimestampNs t_ns, const ImuNoise& settings,
                                   const WhiteNoiseEstimateOptions& options = {});

}  // namespace orbatlas
