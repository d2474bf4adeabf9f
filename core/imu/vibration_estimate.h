#pragma once
// How much of an IMU's measurements no motion of the rig explains at the rates
// the estimator works at: a multirotor's vibration (tens of Hz, broadband) adds
// to the integrated rotation and velocity an error that does not grow with the
// interval, as white noise would, but is there at each end of it. Measured
// from the samples themselves: per axis, the variance of the measurement
// integrated and high-passed (4th-order Butterworth at `corner_hz`, the
// integral's part above it) over the last `window_s` (the median of its
// squares: a brisk move lasts a moment, vibration the whole window), less
// what the settings' white noise puts there. Zero for an IMU on a rig without
// vibration; about 1 mrad and 5 mm/s per axis in EuRoC's flights.
#include <Eigen/Core>
#include <vector>

#include "core/common/timestamp.h"
#include "core/imu/imu_noise.h"
#include "core/io/euroc_types.h"

namespace orbatlas {

struct VibrationEstimateOptions {
  double corner_hz = 6.0;  // the rig's own motion is mostly slower
  // The variance above the corner is scaled by this: vibration reaches below
  // it (the real flights' from 5 Hz), where the filter sees only part of it.
  // With 1.5 the rotation and velocity residuals of the real flights' spectrum
  // have the chi2 of their degrees of freedom (test_imu_vibration.cc).
  double below_corner_factor = 1.5;
  double window_s = 2.0;  // measured over this long before the time asked for
  double settle_s = 0.5;  // the filter runs this long before the window

  // Throws Error naming the first value out of range.
  void check() const;
};

// Of the samples up to `t_ns`. Zero when they do not cover window_s (fewer
// than 50 samples) or have a gap over 50 ms in it.
ImuVibration estimate_vibration(const std::vector<ImuSample>& samples, TimestampNs t_ns, const ImuNoise& noise,
                                const VibrationEstimateOptions& options = {});

}  // namespace orbatlas
