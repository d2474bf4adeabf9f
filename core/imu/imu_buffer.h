#pragma once
// A session's recent IMU samples, in time order, from which the increments
// between two keyframes are preintegrated. One thread at a time (the session's);
// the counters may be read from any thread.
#include <atomic>
#include <cstddef>
#include <optional>
#include <vector>

#include "core/imu/preintegration.h"

namespace orbatlas {

class ImuBuffer {
 public:
  // Samples older than `keep_s` behind the newest are dropped.
  explicit ImuBuffer(double keep_s = 30.0);

  // Each sample after the previous one (throws DataError otherwise, adding none
  // of the batch); non-finite values are refused too.
  void add(const std::vector<ImuSample>& samples);

  // The increments from t0 to t1 (Preintegration::between); empty when the
  // buffer does not cover them (counted in uncovered()).
  std::optional<Preintegration> between(TimestampNs t0, TimestampNs t1, const ImuBias& bias, const ImuNoise& noise,
                                        double max_gap_s = 0.05);

  const std::vector<ImuSample>& samples() const { return samples_; }
  std::size_t size() const { return samples_.size(); }
  std::size_t total() const { return total_.load(); }          // samples added (any thread)
  std::size_t uncovered() const { return uncovered_.load(); }  // between() calls not covered (any thread)

 private:
  double keep_s_;
  std::vector<ImuSample> samples_;
  std::atomic<std::size_t> total_{0}, uncovered_{0};
};

}  // namespace orbatlas
