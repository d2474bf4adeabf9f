#include "core/sim/depth_sensor.h"

#include <cmath>
#include <random>

#include "core/common/error.h"

namespace orbatlas::sim {

void DepthSensorOptions::check() const {
  ORBATLAS_CHECK(depth_map_factor > 0.0 && std::isfinite(depth_map_factor),
                 "depth sensor: depth_map_factor must be > 0, not " << depth_map_factor);
  ORBATLAS_CHECK(min_range_m >= 0.0 && max_range_m > min_range_m && std::isfinite(max_range_m),
                 "depth sensor: the range must satisfy 0 <= min < max, not " << min_range_m << ".." << max_range_m);
  ORBATLAS_CHECK(max_range_m * depth_map_factor < 65535.5, "depth sensor: " << max_range_m
                                                                            << " m does not fit a 16-bit image at "
                                                                            << depth_map_factor << " per metre");
  ORBATLAS_CHECK(noise_per_m2 >= 0.0 && std::isfinite(noise_per_m2), "depth sensor: noise_per_m2 must be >= 0");
  ORBATLAS_CHECK(edge_jump > 0.0, "depth sensor: edge_jump must be > 0, not " << edge_jump);
}

DepthSensor::DepthSensor(const Camera& camera, const DepthSensorOptions& options)
    : options_((options.check(), options)), width_(camera.width()), height_(camera.height()) {
  rays_.resize(static_cast<std::size_t>(width_) * static_cast<std::size_t>(height_));
  for (int v = 0; v < height_; ++v)
    for (int u = 0; u < width_; ++u) {
      const Eigen::Vector3d ray = camera.unproject(Eigen::Vector2d(u, v));
      rays_[static_cast<std::size_t>(v) * static_cast<std::size_t>(width_) + static_cast<std::size_t>(u)] =
          ray.allFinite() && ray.z() > 1e-6 ? ray : Eigen::Vector3d::Zero();
    }
}

cv::Mat DepthSensor::exact(const Renderer& renderer) const {
  cv::Mat z(height_, width_, CV_32FC1, cv::Scalar(0.0f));
  for (int v = 0; v < height_; ++v) {
    float* row = z.ptr<float>(v);
    for (int u = 0; u < width_; ++u) {
      const Eigen::Vector3d& ray =
          rays_[static_cast<std::size_t>(v) * static_cast<std::size_t>(width_) + static_cast<std::size_t>(u)];
      if (ray.z() <= 0.0) continue;
      if (const auto d = renderer.depth_along(ray)) row[u] = static_cast<float>(*d);
    }
  }
  return z;
}

cv::Mat DepthSensor::measure(const Renderer& renderer, std::uint64_t seed) const {
  const cv::Mat z = exact(renderer);
  cv::Mat out(height_, width_, CV_16UC1, cv::Scalar(0));
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> unit(0.0, 1.0);
  const double jump = options_.edge_jump;
  for (int v = 0; v < height_; ++v) {
    std::uint16_t* row = out.ptr<std::uint16_t>(v);
    for (int u = 0; u < width_; ++u) {
      const double d = z.at<float>(v, u);
      if (d < options_.min_range_m || d > options_.max_range_m) continue;
      bool edge = false;
      for (const auto& [du, dv] : {std::pair{-1, 0}, std::pair{1, 0}, std::pair{0, -1}, std::pair{0, 1}}) {
        const int uu = u + du, vv = v + dv;
        if (uu < 0 || vv < 0 || uu >= width_ || vv >= height_) continue;
        const double n = z.at<float>(vv, uu);
        if (n <= 0.0 || std::abs(n - d) > jump * d) edge = true;
      }
      if (edge) continue;
      const double measured = d + options_.noise_per_m2 * d * d * unit(rng);
      const double value = std::round(measured * options_.depth_map_factor);
      if (value >= 1.0 && value <= 65535.0) row[u] = static_cast<std::uint16_t>(value);
    }
  }
  return out;
}

}  // namespace orbatlas::sim
