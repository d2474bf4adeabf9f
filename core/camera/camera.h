#pragma once
// One interface for every camera model: project a point of the camera frame to
// a pixel, unproject a pixel to a unit bearing vector, and the 2x3 Jacobian of
// the projection. Pixel coordinates: (0,0) is the centre of the top-left pixel.
#include <Eigen/Core>
#include <memory>

#include "core/camera/camera_calibration.h"

namespace orbatlas {

class Camera {
 public:
  virtual ~Camera() = default;

  virtual CameraModel model() const = 0;
  int width() const { return width_; }
  int height() const { return height_; }
  bool in_image(const Eigen::Vector2d& uv, double border = 0.0) const;

  // Pixel of p_c (camera frame). False when the point cannot be imaged by the
  // model (behind a pinhole camera, beyond the fisheye's valid angle); uv is
  // then unspecified. Does not check the image bounds.
  virtual bool project(const Eigen::Vector3d& p_c, Eigen::Vector2d* uv) const = 0;

  // Unit bearing vector of a pixel (distortion removed).
  virtual Eigen::Vector3d unproject(const Eigen::Vector2d& uv) const = 0;

  // d(uv)/d(p_c) at p_c; valid where project() returns true.
  virtual Eigen::Matrix<double, 2, 3> project_jacobian(const Eigen::Vector3d& p_c) const = 0;

  virtual CameraCalibration calibration() const = 0;

 protected:
  Camera(int width, int height) : width_(width), height_(height) {}

 private:
  int width_;
  int height_;
};

}  // namespace orbatlas
