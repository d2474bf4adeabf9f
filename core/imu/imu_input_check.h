#pragma once
// What a session's IMU stream may not carry into the estimator: samples that
// are not finite numbers, an axis stuck at one value, readings at the sensor's
// range (saturated). Such samples are dropped, leaving a gap that the
// increments do not bridge (ImuBuffer::between refuses gaps over 50 ms), so
// the frames and keyframes across it are tracked and linked by vision alone.
// Gaps in the stream, a rate far from the settings' IMU.Frequency and frames
// stamped outside what the IMU covers are reported too. Every kind gets one
// warning in the session's status and log the first time it is seen, and a
// count. One thread adds (the session's); health() may be read from any.
#include <cstddef>
#include <deque>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "core/common/timestamp.h"
#include "core/io/euroc_types.h"

namespace orbatlas {

struct ImuInputCheckOptions {
  double rate_hz = 200.0;  // the settings' IMU.Frequency
  // A measured rate off from rate_hz by more than this fraction is reported
  // (the noise densities are discretised at the measured intervals anyway).
  double max_rate_error = 0.25;
  double max_gap_s = 0.05;  // a longer pause between two samples is a gap
  // An axis that repeats one value this many samples in a row while another
  // axis of the same sensor changes is stuck (a real sensor's noise always
  // moves the last digit): its samples are dropped until it moves again.
  std::size_t stuck_samples = 50;
  // The sensor's range (IMU.GyroRange rad/s, IMU.AccRange m/s^2; 0: unknown):
  // a reading at 99.9 % of it or beyond is saturated.
  double gyro_range = 0.0, accel_range = 0.0;
  // A frame stamped further than this from the IMU's samples (before the
  // first, after the last) is one the IMU does not cover.
  double max_frame_distance_s = 0.5;

  // Throws Error naming the first value out of range.
  void check() const;
};

struct ImuInputHealth {
  std::size_t accepted = 0;
  std::size_t non_finite = 0, stuck = 0, saturated = 0;  // samples dropped
  std::size_t gaps = 0;
  double longest_gap_s = 0.0;
  std::optional<double> rate_hz;      // measured (median interval of the latest samples)
  std::size_t frames_outside = 0;     // frames the IMU's stamps do not reach
  std::vector<std::string> warnings;  // the first of each kind, in order

  bool clean() const { return warnings.empty(); }
};

class ImuInputCheck {
 public:
  explicit ImuInputCheck(ImuInputCheckOptions options = {});

  // The samples of `batch` fit to use, in order. Throws DataError, keeping
  // nothing of the batch, when a stamp is not after the previous one.
  std::vector<ImuSample> filter(const std::vector<ImuSample>& batch);
  // A frame at `t_ns` (the camera's clock, `offset_ns` the IMU's ahead of it)
  // against the stream's samples so far (dropped ones too: only the stamps count).
  void check_frame(TimestampNs t_ns, TimestampNs offset_ns = 0);

  ImuInputHealth health() const;
  // Called with each new warning (the session's log); not under the lock.
  void set_warning_sink(std::function<void(const std::string&)> sink) { sink_ = std::move(sink); }

 private:
  void warn(std::vector<std::string>& out, bool& once, const std::string& text);
  bool is_stuck(const ImuSample& s);

  ImuInputCheckOptions options_;
  std::function<void(const std::string&)> sink_;
  std::optional<ImuSample> last_;  // the last sample seen (accepted or not)
  std::optional<TimestampNs> first_seen_;
  // Per axis (gyro x y z, accel x y z): the value repeated and how often in a row.
  double repeated_value_[6] = {};
  std::size_t repeated_count_[6] = {};
  std::deque<TimestampNs> recent_intervals_;
  bool warned_non_finite_ = false, warned_stuck_ = false, warned_saturated_ = false, warned_gap_ = false,
       warned_rate_ = false, warned_frame_ = false;

  mutable std::mutex mutex_;  // guards health_
  ImuInputHealth health_;
};

}  // namespace orbatlas
