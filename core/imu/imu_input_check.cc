#include "core/imu/imu_input_check.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include "core/common/error.h"

namespace orbatlas {
namespace {

constexpr std::size_t kRateIntervals = 400;  // the measured rate: the median of the latest this many

std::string seconds(TimestampNs t) { return format_seconds_exact(t) + " s"; }

std::string fixed(double v, int digits) {
  std::ostringstream s;
  s.precision(digits);
  s << std::fixed << v;
  return s.str();
}

double axis(const ImuSample& s, int a) { return a < 3 ? s.gyro[a] : s.accel[a - 3]; }

}  // namespace

void ImuInputCheckOptions::check() const {
  ORBATLAS_CHECK(std::isfinite(rate_hz) && rate_hz > 0.0, "imu input: rate_hz must be > 0, not " << rate_hz);
  ORBATLAS_CHECK(std::isfinite(max_rate_error) && max_rate_error > 0.0,
                 "imu input: max_rate_error must be > 0, not " << max_rate_error);
  ORBATLAS_CHECK(std::isfinite(max_gap_s) && max_gap_s > 0.0, "imu input: max_gap_s must be > 0, not " << max_gap_s);
  ORBATLAS_CHECK(stuck_samples >= 2, "imu input: stuck_samples must be >= 2, not " << stuck_samples);
  ORBATLAS_CHECK(std::isfinite(gyro_range) && gyro_range >= 0.0,
                 "imu input: gyro_range must be >= 0, not " << gyro_range);
  ORBATLAS_CHECK(std::isfinite(accel_range) && accel_range >= 0.0,
                 "imu input: accel_range must be >= 0, not " << accel_range);
  ORBATLAS_CHECK(std::isfinite(max_frame_distance_s) && max_frame_distance_s > 0.0,
                 "imu input: max_frame_distance_s must be > 0, not " << max_frame_distance_s);
}

ImuInputCheck::ImuInputCheck(ImuInputCheckOptions options) : options_(options) { options_.check(); }

void ImuInputCheck::warn(std::vector<std::string>& out, bool& once, const std::string& text) {
  if (once) return;
  once = true;
  out.push_back(text);
}

bool ImuInputCheck::is_stuck(const ImuSample& s) {
  for (int a = 0; a < 6; ++a) {
    const double v = axis(s, a);
    if (repeated_count_[a] > 0 && v == repeated_value_[a]) {
      ++repeated_count_[a];
    } else {
      repeated_value_[a] = v;
      repeated_count_[a] = 1;
    }
  }
  // An axis repeating while another of its sensor moves (all three still: a
  // sensor without noise, as in a test, or one that stopped altogether, which
  // the gyro's and accelerometer's other checks see).
  for (int sensor = 0; sensor < 2; ++sensor) {
    bool repeating = false, moving = false;
    for (int a = 3 * sensor; a < 3 * sensor + 3; ++a) {
      if (repeated_count_[a] >= options_.stuck_samples) repeating = true;
      if (repeated_count_[a] < options_.stuck_samples) moving = true;
    }
    if (repeating && moving) return true;
  }
  return false;
}

std::vector<ImuSample> ImuInputCheck::filter(const std::vector<ImuSample>& batch) {
  TimestampNs previous = last_ ? last_->t_ns : std::numeric_limits<TimestampNs>::min();
  for (std::size_t i = 0; i < batch.size(); ++i) {
    ORBATLAS_DATA_CHECK(batch[i].t_ns > previous, "imu: sample " << i << " at " << seconds(batch[i].t_ns)
                                                                 << " is not after the previous one ("
                                                                 << seconds(previous) << ")");
    previous = batch[i].t_ns;
  }
  std::vector<ImuSample> out;
  out.reserve(batch.size());
  std::vector<std::string> new_warnings;
  {
    std::lock_guard lock(mutex_);
    ImuInputHealth& h = health_;
    for (const ImuSample& s : batch) {
      if (last_) {
        const TimestampNs dt = s.t_ns - last_->t_ns;
        if (ns_to_s(dt) > options_.max_gap_s) {
          ++h.gaps;
          h.longest_gap_s = std::max(h.longest_gap_s, ns_to_s(dt));
          warn(new_warnings, warned_gap_,
               "IMU gap of " + fixed(ns_to_s(dt) * 1e3, 0) + " ms before " + seconds(s.t_ns) +
                   ": frames across it are tracked without the IMU");
        } else {
          recent_intervals_.push_back(dt);
          if (recent_intervals_.size() > kRateIntervals) recent_intervals_.pop_front();
        }
      }
      last_ = s;
      if (!first_seen_) first_seen_ = s.t_ns;
      if (!s.gyro.allFinite() || !s.accel.allFinite()) {
        ++h.non_finite;
        warn(new_warnings, warned_non_finite_,
             "IMU sample at " + seconds(s.t_ns) + " is not a finite number: dropped (and every such sample)");
        continue;
      }
      const bool gyro_saturated =
          options_.gyro_range > 0.0 && s.gyro.cwiseAbs().maxCoeff() >= 0.999 * options_.gyro_range;
      const bool accel_saturated =
          options_.accel_range > 0.0 && s.accel.cwiseAbs().maxCoeff() >= 0.999 * options_.accel_range;
      if (gyro_saturated || accel_saturated) {
        ++h.saturated;
        warn(new_warnings, warned_saturated_,
             std::string("IMU ") + (gyro_saturated ? "gyro" : "accelerometer") + " saturated at " + seconds(s.t_ns) +
                 " (range " + fixed(gyro_saturated ? options_.gyro_range : options_.accel_range, 2) +
                 "): its samples at the range are dropped");
        is_stuck(s);  // keeps the per-axis runs going
        continue;
      }
      if (is_stuck(s)) {
        ++h.stuck;
        warn(new_warnings, warned_stuck_,
             "IMU axis stuck at " + seconds(s.t_ns) + " (one value " + std::to_string(options_.stuck_samples) +
                 " samples in a row while the others move): dropped until it moves");
        continue;
      }
      out.push_back(s);
      ++h.accepted;
    }
    if (recent_intervals_.size() >= kRateIntervals / 2) {
      std::vector<TimestampNs> v(recent_intervals_.begin(), recent_intervals_.end());
      std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
      const double rate = 1.0 / ns_to_s(v[v.size() / 2]);
      h.rate_hz = rate;
      if (std::abs(rate / options_.rate_hz - 1.0) > options_.max_rate_error)
        warn(new_warnings, warned_rate_,
             "IMU runs at " + fixed(rate, 1) + " Hz, the settings say " + fixed(options_.rate_hz, 1) +
                 " Hz (IMU.Frequency): its noise is weighed by the measured intervals");
    }
    h.warnings.insert(h.warnings.end(), new_warnings.begin(), new_warnings.end());
  }
  if (sink_)
    for (const auto& w : new_warnings) sink_(w);
  return out;
}

void ImuInputCheck::check_frame(TimestampNs t_ns, TimestampNs offset_ns) {
  if (!first_seen_) return;  // no IMU yet: the session has not begun to send it
  const TimestampNs t = t_ns + offset_ns;
  const TimestampNs tolerance = s_to_ns(options_.max_frame_distance_s);
  if (t >= *first_seen_ - tolerance && t <= last_->t_ns + tolerance) return;
  std::vector<std::string> new_warnings;
  {
    std::lock_guard lock(mutex_);
    ++health_.frames_outside;
    warn(new_warnings, warned_frame_,
         "frame at " + seconds(t_ns) + " is " +
             fixed(ns_to_s(t < *first_seen_ ? *first_seen_ - t : t - last_->t_ns), 3) + " s " +
             (t < *first_seen_ ? "before the first" : "after the last") +
             " IMU sample: the IMU's stamps and the camera's are apart (or the IMU stopped); such frames are "
             "tracked without it");
    health_.warnings.insert(health_.warnings.end(), new_warnings.begin(), new_warnings.end());
  }
  if (sink_)
    for (const auto& w : new_warnings) sink_(w);
}

ImuInputHealth ImuInputCheck::health() const {
  std::lock_guard lock(mutex_);
  return health_;
}

}  // namespace orbatlas
