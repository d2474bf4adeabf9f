#include "core/imu/vibration_estimate.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "core/common/error.h"

namespace orbatlas {
namespace {

// A second-order section, designed from H(s) = (b2 s^2 + b1 s + b0) /
// (s^2 + a1 s + a0) by the bilinear transform at sample interval dt.
struct Biquad {
  double b0 = 0, b1 = 0, b2 = 0, a1 = 0, a2 = 0;
  Biquad(double sb2, double sb1, double sb0, double sa1, double sa0, double dt) {
    const double k = 2.0 / dt, k2 = k * k;
    const double norm = k2 + sa1 * k + sa0;
    b0 = (sb2 * k2 + sb1 * k + sb0) / norm;
    b1 = (-2.0 * sb2 * k2 + 2.0 * sb0) / norm;
    b2 = (sb2 * k2 - sb1 * k + sb0) / norm;
    a1 = (-2.0 * k2 + 2.0 * sa0) / norm;
    a2 = (k2 - sa1 * k + sa0) / norm;
  }
  // Direct form II transposed, one state per channel.
  double step(double x, double& z1, double& z2) const {
    const double y = b0 * x + z1;
    z1 = b1 * x - a1 * y + z2;
    z2 = b2 * x - a2 * y;
    return y;
  }
};

}  // namespace

void VibrationEstimateOptions::check() const {
  ORBATLAS_CHECK(std::isfinite(corner_hz) && corner_hz > 0.0,
                 "vibration estimate: corner_hz must be > 0, not " << corner_hz);
  ORBATLAS_CHECK(std::isfinite(below_corner_factor) && below_corner_factor >= 1.0,
                 "vibration estimate: below_corner_factor must be >= 1, not " << below_corner_factor);
  ORBATLAS_CHECK(std::isfinite(window_s) && window_s > 0.0,
                 "vibration estimate: window_s must be > 0, not " << window_s);
  ORBATLAS_CHECK(std::isfinite(settle_s) && settle_s >= 0.0,
                 "vibration estimate: settle_s must be >= 0, not " << settle_s);
}

ImuVibration estimate_vibration(const std::vector<ImuSample>& samples, TimestampNs t_ns, const ImuNoise& noise,
                                const VibrationEstimateOptions& options) {
  ImuVibration out;
  const TimestampNs window_start = t_ns - s_to_ns(options.window_s);
  const TimestampNs first = window_start - s_to_ns(options.settle_s);
  const auto begin = std::lower_bound(samples.begin(), samples.end(), first,
                                      [](const ImuSample& s, TimestampNs t) { return s.t_ns < t; });
  const auto end =
      std::upper_bound(begin, samples.end(), t_ns, [](TimestampNs t, const ImuSample& s) { return t < s.t_ns; });
  const auto count = std::distance(begin, end);
  if (count < 50 || begin->t_ns > window_start) return out;
  const double dt = ns_to_s((end - 1)->t_ns - begin->t_ns) / static_cast<double>(count - 1);
  for (auto it = begin + 1; it != end; ++it)
    if (ns_to_s(it->t_ns - (it - 1)->t_ns) > 0.05) return out;

  // The integral's part above the corner: s^3 / B4(s), a 4th-order
  // Butterworth high-pass divided by s, as two sections (high-pass, band-pass).
  const double w = 2.0 * M_PI * options.corner_hz;
  const Biquad high(1.0, 0.0, 0.0, 0.76537 * w, w * w, dt);
  const Biquad band(0.0, 1.0, 0.0, 1.84776 * w, w * w, dt);
  std::array<std::array<double, 4>, 6> z{};  // per channel: the two sections' states
  std::array<std::vector<double>, 6> squares;
  for (auto it = begin; it != end; ++it) {
    Eigen::Matrix<double, 6, 1> x;
    x << it->gyro, it->accel;
    for (int c = 0; c < 6; ++c) {
      const double h = high.step(x[c], z[c][0], z[c][1]);
      const double r = band.step(h, z[c][2], z[c][3]);
      if (it->t_ns >= window_start) squares[c].push_back(r * r);
    }
  }
  if (squares[0].empty()) return out;
  // The median: a brisk move of the rig (its motion above the corner) lasts a
  // moment, vibration the whole window. For Gaussian values the median of the
  // squares is 0.4549 of their variance.
  Eigen::Matrix<double, 6, 1> variance;
  for (int c = 0; c < 6; ++c) {
    auto& v = squares[c];
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    variance[c] = v[v.size() / 2] / 0.4549;
  }
  // White noise of density d leaves d^2 * 1.026 / (4 pi^2 f_c) there
  // (the integral of |H|^2 over frequency).
  const double white = 1.026 / (4.0 * M_PI * M_PI * options.corner_hz);
  const double gyro_white = noise.gyro_density * noise.gyro_density * white;
  const double accel_white = noise.accel_density * noise.accel_density * white;
  for (int a = 0; a < 3; ++a) {
    out.rotation_var[a] = options.below_corner_factor * std::max(0.0, variance[a] - gyro_white);
    out.velocity_var[a] = options.below_corner_factor * std::max(0.0, variance[3 + a] - accel_white);
  }
  return out;
}

}  // namespace orbatlas
