#include "core/sim/real_camera.h"

#include <algorithm>
#include <cmath>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "core/common/error.h"

namespace orbatlas::sim {

RealCamera::RealCamera(const RealCameraOptions& options, int width, int height, int camera_index, std::uint64_t seed)
    : options_(options) {
  options.check();
  std::mt19937_64 rng(seed * 0x9E3779B97F4A7C15ULL + static_cast<std::uint64_t>(camera_index) * 7919ULL + 11ULL);
  std::uniform_real_distribution<double> uni(0.0, 2.0 * M_PI);
  phase1_ = uni(rng);
  phase2_ = uni(rng);
  // The two cameras' static gain mismatch: one brighter, one darker.
  const double half = 0.5 * options.stereo_mismatch * std::uniform_real_distribution<double>(0.5, 1.0)(rng);
  offset_ = camera_index == 0 ? 1.0 + half : 1.0 - half;

  vignette_.create(height, width, CV_32FC1);
  const double cx = 0.5 * (width - 1), cy = 0.5 * (height - 1);
  const double corner2 = cx * cx + cy * cy;
  for (int v = 0; v < height; ++v) {
    float* row = vignette_.ptr<float>(v);
    for (int u = 0; u < width; ++u) {
      const double r2 = ((u - cx) * (u - cx) + (v - cy) * (v - cy)) / corner2;  // 1 at the corners
      row[u] = static_cast<float>(1.0 - options.vignetting * std::pow(r2, 1.25));
    }
  }
}

Exposure RealCamera::exposure_at(TimestampNs t) const {
  const RealCameraOptions& o = options_;
  Exposure e;
  // Auto exposure: longer exposure first, then gain, within their limits.
  const double wanted_ms = o.base_exposure_ms / o.illumination;
  const double exposure_ms = std::min(wanted_ms, o.max_exposure_ms);
  const double delivered = o.illumination * exposure_ms / o.base_exposure_ms;  // before gain
  e.gain = std::clamp(1.0 / delivered, 1.0, o.max_gain);
  e.exposure_s = exposure_ms * 1e-3;
  // It hunts around its target with a lag: slow drift, different per camera.
  const double ts = static_cast<double>(t) * 1e-9;
  const double w = 2.0 * M_PI / o.drift_period_s;
  const double drift = 1.0 + o.drift * (0.65 * std::sin(w * ts + phase1_) + 0.35 * std::sin(2.7 * w * ts + phase2_));
  e.brightness = delivered * e.gain * drift * offset_;
  return e;
}

int RealCamera::subframes(double motion_px_per_s, double exposure_s) const {
  const double blur_px = std::max(0.0, motion_px_per_s) * exposure_s;
  const int n = static_cast<int>(std::ceil(blur_px / std::max(0.1, options_.blur_px_per_subframe)));
  return std::clamp(n, 1, std::max(1, options_.max_blur_subframes));
}

void RealCamera::develop(const cv::Mat& radiance, const Exposure& exposure, cv::Mat& image,
                         std::uint64_t noise_seed) const {
  ORBATLAS_CHECK(radiance.type() == CV_32FC1 && radiance.size() == vignette_.size(),
                 "real look: radiance of the wrong size or type");
  cv::Mat signal;
  cv::multiply(radiance, vignette_, signal, exposure.brightness);
  if (options_.optics_blur_px > 0.0) cv::GaussianBlur(signal, signal, cv::Size(0, 0), options_.optics_blur_px);
  // Noise: read noise amplified by the gain, shot noise growing with the signal.
  cv::Mat variance;
  cv::max(signal, 0.0, variance);
  variance = variance * (options_.shot_noise * exposure.gain) +
             (options_.read_noise * exposure.gain) * (options_.read_noise * exposure.gain);
  cv::Mat sigma;
  cv::sqrt(variance, sigma);
  cv::Mat noise(signal.size(), CV_32FC1);
  cv::RNG rng(noise_seed == 0 ? 1 : noise_seed);
  rng.fill(noise, cv::RNG::NORMAL, 0.0, 1.0);
  cv::Mat noisy = signal + noise.mul(sigma);
  noisy.convertTo(image, CV_8UC1);  // rounds and clips to [0, 255]
}

}  // namespace orbatlas::sim
