#pragma once
// A depth camera registered to a rendered camera (`orbatlas sim --depth`):
// per image pixel the depth (z in the camera frame) the renderer
// drew along that pixel's ray, made as a structured-light sensor measures it:
// Gaussian noise growing with the square of the depth (constant in disparity;
// Khoshelham and Elberink 2012 measured 1.425e-3 z^2 for the Kinect), no depth
// outside the sensor's range, holes where the depth jumps between neighbouring
// pixels (object edges: the projector's pattern is occluded there), and the
// value quantised to the 16-bit image of the TUM RGB-D layout.
#include <cstdint>
#include <opencv2/core/mat.hpp>
#include <vector>

#include "core/camera/camera.h"
#include "core/sim/renderer.h"

namespace orbatlas::sim {

struct DepthSensorOptions {
  double depth_map_factor = 5000.0;  // image value per metre (TUM: 5000)
  double min_range_m = 0.4;
  double max_range_m = 10.0;
  double noise_per_m2 = 1.425e-3;  // sigma_z = noise_per_m2 * z^2 (0: exact depth)
  double edge_jump = 0.05;         // a neighbour this much nearer or farther (relative): a hole

  // Throws Error naming the first value out of range.
  void check() const;
};

class DepthSensor {
 public:
  // Precomputes the ray of every pixel of `camera` (which must outlive nothing: the rays are copied).
  DepthSensor(const Camera& camera, const DepthSensorOptions& options = {});

  // The depth image (CV_16UC1, 0 where none) of the renderer's last render,
  // which must be of the same camera. `seed` makes the noise reproducible.
  cv::Mat measure(const Renderer& renderer, std::uint64_t seed) const;
  // The rendered depth in metres before noise, range and quantisation (CV_32FC1, 0 where nothing).
  cv::Mat exact(const Renderer& renderer) const;

  const DepthSensorOptions& options() const { return options_; }

 private:
  DepthSensorOptions options_;
  int width_, height_;
  std::vector<Eigen::Vector3d> rays_;  // per pixel, row-major; z = 0 where the model has none
};

}  // namespace orbatlas::sim
