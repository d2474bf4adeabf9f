#include "core/sim/imu_vibration.h"

#include <algorithm>
#include <cmath>
#include <opencv2/core.hpp>

#include "core/common/error.h"

namespace orbatlas::sim {
namespace {

Eigen::Vector3d band_rms(const std::vector<Eigen::Vector3d>& density, double first_hz, double band_hz,
                         double nyquist_hz) {
  Eigen::Vector3d power = Eigen::Vector3d::Zero();
  for (std::size_t b = 0; b < density.size(); ++b) {
    const double lo = first_hz + band_hz * static_cast<double>(b);
    const double width = std::clamp(nyquist_hz - lo, 0.0, band_hz);
    power += density[b].cwiseAbs2() * width;
  }
  return power.cwiseSqrt();
}

}  // namespace

Eigen::Vector3d VibrationSpectrum::gyro_rms(double nyquist_hz) const {
  return band_rms(gyro, first_hz, band_hz, nyquist_hz);
}

Eigen::Vector3d VibrationSpectrum::accel_rms(double nyquist_hz) const {
  return band_rms(accel, first_hz, band_hz, nyquist_hz);
}

const VibrationSpectrum& euroc_flight_vibration() {
  // scripts/analysis/imu_spectrum.py on the real MH_05 IMU, 40-100 s (Welch, 1024
  // samples a segment), the mean power of each 5-Hz band, square-rooted.
  static const VibrationSpectrum spectrum = [] {
    VibrationSpectrum s;
    s.first_hz = 5.0;
    s.band_hz = 5.0;
    s.gyro = {{0.00499, 0.00917, 0.01233}, {0.00419, 0.01030, 0.01066}, {0.00328, 0.01067, 0.00726},
              {0.00425, 0.00477, 0.00631}, {0.00747, 0.00159, 0.00433}, {0.00338, 0.00119, 0.00198},
              {0.00142, 0.00094, 0.00095}, {0.00071, 0.00111, 0.00066}, {0.00056, 0.00120, 0.00079},
              {0.00060, 0.00139, 0.00144}, {0.00043, 0.00140, 0.00098}, {0.00052, 0.00171, 0.00105},
              {0.00039, 0.00189, 0.00094}, {0.00043, 0.00258, 0.00133}, {0.00068, 0.00318, 0.00209},
              {0.00130, 0.00794, 0.00440}, {0.00128, 0.00831, 0.00531}, {0.00131, 0.00839, 0.00532},
              {0.00080, 0.00432, 0.00252}};
    s.accel = {{0.0685, 0.0226, 0.0475}, {0.1023, 0.0270, 0.0524}, {0.1200, 0.0311, 0.0549}, {0.0809, 0.0572, 0.0569},
               {0.0589, 0.1279, 0.0535}, {0.0535, 0.0666, 0.0538}, {0.0520, 0.0355, 0.0493}, {0.0600, 0.0256, 0.0534},
               {0.0573, 0.0234, 0.0498}, {0.0597, 0.0281, 0.0542}, {0.0598, 0.0327, 0.0569}, {0.0609, 0.0351, 0.0584},
               {0.0675, 0.0354, 0.0621}, {0.0891, 0.0444, 0.0660}, {0.0873, 0.0589, 0.0621}, {0.1666, 0.0612, 0.0932},
               {0.1922, 0.0549, 0.1101}, {0.1982, 0.0554, 0.1200}, {0.1186, 0.0424, 0.0803}};
    return s;
  }();
  return spectrum;
}

std::vector<Eigen::Vector3d> shaped_noise(const std::vector<Eigen::Vector3d>& density, double first_hz, double band_hz,
                                          std::size_t count, double rate_hz, std::mt19937_64& rng) {
  ORBATLAS_CHECK(rate_hz > 0.0 && band_hz > 0.0 && first_hz >= 0.0, "shaped noise: bad rate or bands");
  std::vector<Eigen::Vector3d> out(count, Eigen::Vector3d::Zero());
  if (count < 2 || density.empty()) return out;
  const int n = cv::getOptimalDFTSize(static_cast<int>(count));
  std::normal_distribution<double> normal(0.0, 1.0);
  for (int axis = 0; axis < 3; ++axis) {
    // White noise of unit variance has the one-sided density 2 / rate; each
    // bin is scaled to the density wanted at its frequency.
    cv::Mat white(1, n, CV_64F);
    for (int k = 0; k < n; ++k) white.at<double>(0, k) = normal(rng);
    cv::Mat spectrum;
    cv::dft(white, spectrum, cv::DFT_COMPLEX_OUTPUT);
    for (int k = 0; k < n; ++k) {
      const int folded = std::min(k, n - k);
      const double hz = rate_hz * folded / n;
      const double band = std::floor((hz - first_hz) / band_hz);
      double gain = 0.0;
      if (band >= 0.0 && band < static_cast<double>(density.size()))
        gain = density[static_cast<std::size_t>(band)][axis] * std::sqrt(rate_hz / 2.0);
      spectrum.at<cv::Vec2d>(0, k) *= gain;
    }
    cv::Mat shaped;
    cv::idft(spectrum, shaped, cv::DFT_REAL_OUTPUT | cv::DFT_SCALE);
    for (std::size_t k = 0; k < count; ++k) out[k][axis] = shaped.at<double>(0, static_cast<int>(k));
  }
  return out;
}

double MotorSchedule::level(TimestampNs t) const {
  // Linear ramps of 1 s: up to idle before idle_from, up to flight before
  // take-off, down to nothing after landing.
  const auto ramp = [](TimestampNs from, TimestampNs now) {
    return std::clamp(ns_to_s(now - from) + 1.0, 0.0, 1.0);  // 0 one second before `from`, 1 at it
  };
  if (t >= landing_ns) return std::clamp(1.0 - ns_to_s(t - landing_ns), 0.0, 1.0);
  return std::max(idle_level * ramp(idle_from_ns, t), ramp(takeoff_ns, t));
}

MotorSchedule motor_schedule(const TrajectorySpline& trajectory, double idle_s) {
  constexpr double kStillSpeed = 0.05;  // m/s
  constexpr double kMinStillS = 2.0;    // s
  const TimestampNs step = kNsPerSecond / 20;
  struct Stretch {
    TimestampNs from, to;
  };
  std::vector<Stretch> still;
  bool is_still = false;
  TimestampNs since = 0;
  const auto close = [&](TimestampNs end) {
    if (is_still && ns_to_s(end - since) >= kMinStillS) still.push_back({since, end});
    is_still = false;
  };
  for (TimestampNs t = trajectory.start_ns(); t <= trajectory.end_ns(); t += step) {
    if (trajectory.evaluate(t).v_w.norm() < kStillSpeed) {
      if (!is_still) since = t;
      is_still = true;
    } else {
      close(t);
    }
  }
  close(trajectory.end_ns());
  const TimestampNs middle = trajectory.start_ns() + (trajectory.end_ns() - trajectory.start_ns()) / 2;
  MotorSchedule s;
  s.takeoff_ns = trajectory.start_ns() - kNsPerSecond;  // flying from the start unless parked below
  s.landing_ns = trajectory.end_ns() + 2 * kNsPerSecond;
  for (const Stretch& r : still) {
    if (r.from < middle) s.takeoff_ns = r.to;
    if (r.from >= middle && s.landing_ns > trajectory.end_ns()) s.landing_ns = r.from;
  }
  s.idle_from_ns = s.takeoff_ns - s_to_ns(idle_s);
  return s;
}

}  // namespace orbatlas::sim
