#pragma once
// Software renderer for a World of textured quads, through a real (distorted)
// camera model. Each frame is rasterised into an undistorted pinhole "canvas"
// that covers the camera's field of view, with a z-buffer and mip-mapped bilinear
// texture sampling; a precomputed remap then applies the lens distortion, and
// image noise is added. One Renderer per thread: it owns its scratch buffers and
// only reads the World.
#include <cstdint>
#include <memory>
#include <optional>
#include <opencv2/core/mat.hpp>
#include <utility>
#include <vector>

#include "core/camera/camera.h"
#include "core/geometry/pose.h"
#include "core/sim/world.h"

namespace orbatlas::sim {

struct RenderOptions {
  double noise_sigma = 2.0;  // grey levels, Gaussian, added after the lens
  double near_m = 0.05;
  // The canvas is never larger than this factor times the image (fisheye lenses
  // see beyond what a pinhole canvas can hold; those pixels stay black).
  double max_canvas_scale = 2.5;
  // Canvas focal length relative to the camera's. Barrel distortion squeezes
  // the image periphery, so a canvas at full focal length spends ~45% of its
  // samples on detail the image cannot show; at 0.8 the centre is upsampled by
  // 1.25 (a softness comparable to the real EuRoC optics) and rendering is ~1.5x faster.
  double canvas_focal_scale = 0.8;

  // Throws Error naming the first value out of range.
  void check() const;
};

class Renderer {
 public:
  Renderer(const World& world, const Camera& camera, const RenderOptions& options = {});

  // Renders the camera at T_w_c into a CV_8UC1 image of the camera's size.
  // noise_seed makes the image noise reproducible per frame.
  void render(const Pose3& T_w_c, cv::Mat& image, std::uint64_t noise_seed);

  // The undistorted canvas of the last render (for tests and debugging).
  const cv::Mat& canvas() const { return canvas_; }
  // Depth (z in the camera frame) of the last render on the canvas; +inf where empty.
  const cv::Mat& canvas_depth() const { return zbuffer_; }
  // Rendered depth (z in the camera frame) along a ray of the camera frame, from
  // the nearest canvas pixel of the last render; empty outside the canvas or
  // where nothing was drawn. Ground truth for depth-estimation tests.
  std::optional<double> depth_along(const Eigen::Vector3d& ray_c) const;

 private:
  void rasterize_quad(const Quad& quad, const Eigen::Matrix3d& R_c_w, const Eigen::Vector3d& t_c_w);
  void add_noise(cv::Mat& image, std::uint64_t seed) const;

  const World& world_;
  RenderOptions options_;
  int width_, height_;
  // Canvas: pinhole with the camera's focal lengths and a principal point that
  // makes it cover every pixel of the distorted image.
  double fx_, fy_, cx_, cy_;
  cv::Mat canvas_;                        // CV_8UC1
  cv::Mat zbuffer_;                       // CV_32FC1
  std::vector<int> row_begin_, row_end_;  // per canvas row, columns the remap reads [begin, end)
  cv::Mat map1_, map2_;                   // fixed-point remap tables image -> canvas
  std::vector<std::int16_t> noise_table_;
  std::vector<std::pair<double, std::size_t>> draw_order_;  // (squared distance, quad index)
};

}  // namespace orbatlas::sim
