#pragma once
// A session's recent IMU samples, in time order, from which the increments
// between two frames or keyframes are preintegrated. One thread at a time (the
// session's); the sample count may be read from any thread.
#include <atomic>
#include <cstddef>
#include <optional>
#include <vector>

#include "core/imu/preintegration.h"

namespace orbatlas {

class ImuBuffer {
 public:
  // Samples older than `keep_s` behind the newest are dropped. With
  // `measure_vibration`, the increments between() makes carry the vibration
  // measured in the samples before their end (vibration_estimate.h); with
  // `measure_white_noise`, the white noise measured there where it is above
  // the settings' (white_noise_estimate.h).
  explicit ImuBuffer(double keep_s = 30.0, bool measure_vibration = true, bool measure_white_noise = true);

  // Each sample after the previous one (throws DataError otherwise, adding none
  // of the batch); non-finite values are refused too.
  void add(const std::vector<ImuSample>& samples);

  // The camera's clock against the IMU's: an image stamped t was taken at IMU
  // time t + offset (ImuTimeOffset estimates it). Every time asked of the
  // buffer is a camera time, shifted by it.
  void set_time_offset(TimestampNs offset_ns) { time_offset_ns_ = offset_ns; }
  TimestampNs time_offset() const { return time_offset_ns_; }

  // The increments from t0 to t1 (Preintegration::between) with measured(t1,
  // noise); empty when the buffer does not cover them.
  std::optional<Preintegration> between(TimestampNs t0, TimestampNs t1, const ImuBias& bias, const ImuNoise& noise,
                                        double max_gap_s = 0.05) const;
  // `noise` with the white noise and the vibration measured in the samples up
  // to t (each as the settings' without measuring it).
  ImuNoise measured(TimestampNs t, const ImuNoise& noise) const;
  // The mean specific force (IMU frame) of the samples in the `window_s`
  // seconds up to t; none with fewer than `min_samples` there.
  std::optional<Eigen::Vector3d> mean_accel(TimestampNs t, double window_s, std::size_t min_samples) const;

  const std::vector<ImuSample>& samples() const { return samples_; }
  std::size_t size() const { return samples_.size(); }
  std::size_t total() const { return total_.load(); }  // samples added (any thread)

 private:
  double keep_s_;
  bool measure_vibration_;
  bool measure_white_noise_;
  TimestampNs time_offset_ns_ = 0;
  std::vector<ImuSample> samples_;
  std::atomic<std::size_t> total_{0};
};

}  // namespace orbatlas
