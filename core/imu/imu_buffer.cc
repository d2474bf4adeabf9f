#include "core/imu/imu_buffer.h"

#include <algorithm>
#include <limits>

#include "core/common/error.h"
#include "core/imu/vibration_estimate.h"
#include "core/imu/white_noise_estimate.h"

namespace orbatlas {

ImuBuffer::ImuBuffer(double keep_s, bool measure_vibration, bool measure_white_noise)
    : keep_s_(keep_s), measure_vibration_(measure_vibration), measure_white_noise_(measure_white_noise) {
  ORBATLAS_CHECK(keep_s > 0.0, "imu buffer: keep_s must be > 0, not " << keep_s);
}

void ImuBuffer::add(const std::vector<ImuSample>& samples) {
  TimestampNs last = samples_.empty() ? std::numeric_limits<TimestampNs>::min() : samples_.back().t_ns;
  for (const ImuSample& s : samples) {
    ORBATLAS_DATA_CHECK(s.t_ns > last,
                        "imu: sample at " << format_seconds_exact(s.t_ns) << " s is not after the previous one");
    ORBATLAS_DATA_CHECK(s.gyro.allFinite() && s.accel.allFinite(),
                        "imu: sample at " << format_seconds_exact(s.t_ns) << " s is not finite");
    last = s.t_ns;
  }
  samples_.insert(samples_.end(), samples.begin(), samples.end());
  total_ += samples.size();
  if (samples_.empty()) return;
  const TimestampNs oldest = samples_.back().t_ns - s_to_ns(keep_s_);
  const auto keep = std::lower_bound(samples_.begin(), samples_.end(), oldest,
                                     [](const ImuSample& s, TimestampNs t) { return s.t_ns < t; });
  if (keep - samples_.begin() > static_cast<std::ptrdiff_t>(samples_.size() / 2))
    samples_.erase(samples_.begin(), keep);  // amortised: at most every other call moves the rest
}

ImuNoise ImuBuffer::measured(TimestampNs t, const ImuNoise& noise) const {
  const TimestampNs at = t + time_offset_ns_;
  ImuNoise out = measure_white_noise_ ? with_measured_white_noise(samples_, at, noise) : noise;
  // The vibration beyond the white noise just measured.
  if (measure_vibration_) out.vibration = estimate_vibration(samples_, at, out);
  return out;
}

std::optional<Eigen::Vector3d> ImuBuffer::mean_accel(TimestampNs t, double window_s, std::size_t min_samples) const {
  const TimestampNs end = t + time_offset_ns_, begin = end - s_to_ns(window_s);
  const auto first = std::lower_bound(samples_.begin(), samples_.end(), begin,
                                      [](const ImuSample& s, TimestampNs at) { return s.t_ns < at; });
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  std::size_t n = 0;
  for (auto it = first; it != samples_.end() && it->t_ns <= end; ++it, ++n) sum += it->accel;
  if (n == 0 || n < min_samples) return std::nullopt;
  return sum / static_cast<double>(n);
}

std::optional<Preintegration> ImuBuffer::between(TimestampNs t0, TimestampNs t1, const ImuBias& bias,
                                                 const ImuNoise& noise, double max_gap_s) const {
  try {
    return Preintegration::between(samples_, t0 + time_offset_ns_, t1 + time_offset_ns_, bias, measured(t1, noise),
                                   max_gap_s);
  } catch (const DataError&) {
    return std::nullopt;
  }
}

}  // namespace orbatlas
