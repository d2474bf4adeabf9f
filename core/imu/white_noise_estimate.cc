#include "core/imu/white_noise_estimate.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "core/common/error.h"

namespace orbatlas {
namespace {

// For Gaussian values, the mean of the lowest 90 % of the squares is 0.6228 of
// their variance.
constexpr double kTrimmedMeanOfSquares = 0.6228;

double trimmed_variance(std::vector<double>& squares) {
  const auto keep = static_cast<std::ptrdiff_t>(0.9 * static_cast<double>(squares.size()));
  std::nth_element(squares.begin(), squares.begin() + keep, squares.end());
  double sum = 0.0;
  for (auto it = squares.begin(); it != squares.begin() + keep; ++it) sum += *it;
  return sum / static_cast<double>(keep) / kTrimmedMeanOfSquares;
}

}  // namespace

void WhiteNoiseEstimateOptions::check() const {
  ORBATLAS_CHECK(std::isfinite(window_s) && window_s > 0.0,
                 "white noise estimate: window_s must be > 0, not " << window_s);
  ORBATLAS_CHECK(std::isfinite(max_factor) && max_factor >= 1.0,
                 "white noise estimate: max_factor must be >= 1, not " << max_factor);
}

std::optional<WhiteNoiseDensities> measure_white_noise(const std::vector<ImuSample>& samples, TimestampNs t_ns,
                                                       const WhiteNoiseEstimateOptions& options) {
  const TimestampNs first = t_ns - s_to_ns(options.window_s);
  const auto begin = std::lower_bound(samples.begin(), samples.end(), first,
                                      [](const ImuSample& s, TimestampNs t) { return s.t_ns < t; });
  const auto end =
      std::upper_bound(begin, samples.end(), t_ns, [](TimestampNs t, const ImuSample& s) { return t < s.t_ns; });
  const auto count = std::distance(begin, end);
  // The window must be covered: its first sample within 50 ms of its start.
  if (count < 50 || ns_to_s(begin->t_ns - first) > 0.05) return std::nullopt;
  std::array<std::vector<double>, 6> squares;
  for (auto& s : squares) s.reserve(static_cast<std::size_t>(count));
  for (auto it = begin + 1; it != end; ++it)
    if (ns_to_s(it->t_ns - (it - 1)->t_ns) > 0.05) return std::nullopt;
  for (auto it = begin + 1; it + 1 != end; ++it) {
    Eigen::Matrix<double, 6, 1> d;
    d << (it + 1)->gyro - 2.0 * it->gyro + (it - 1)->gyro, (it + 1)->accel - 2.0 * it->accel + (it - 1)->accel;
    for (int c = 0; c < 6; ++c) squares[c].push_back(d[c] * d[c]);
  }
  const double dt = ns_to_s((end - 1)->t_ns - begin->t_ns) / static_cast<double>(count - 1);
  // A second difference of white noise has six times its variance per
  // sample, density^2 / dt.
  double gyro = 0.0, accel = 0.0;
  for (int a = 0; a < 3; ++a) {
    gyro += trimmed_variance(squares[a]) / 6.0 * dt / 3.0;
    accel += trimmed_variance(squares[3 + a]) / 6.0 * dt / 3.0;
  }
  return WhiteNoiseDensities{std::sqrt(gyro), std::sqrt(accel)};
}

ImuNoise with_measured_white_noise(const std::vector<ImuSample>& samples, TimestampNs t_ns, const ImuNoise& settings,
                                   const WhiteNoiseEstimateOptions& options) {
  ImuNoise out = settings;
  if (const auto measured = measure_white_noise(samples, t_ns, options)) {
    out.gyro_density = std::clamp(measured->gyro, settings.gyro_density, options.max_factor * settings.gyro_density);
    out.accel_density =
        std::clamp(measured->accel, settings.accel_density, options.max_factor * settings.accel_density);
  }
  return out;
}

}  // namespace orbatlas
