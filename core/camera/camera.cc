#include "core/camera/camera.h"

namespace orbatlas {

bool Camera::in_image(const Eigen::Vector2d& uv, double border) const {
  // Pixel centres run from 0 to size - 1 (see camera.h).
  return uv.x() >= border && uv.y() >= border && uv.x() <= width_ - 1 - border && uv.y() <= height_ - 1 - border;
}

const char* camera_model_name(CameraModel model) {
  switch (model) {
    case CameraModel::kPinholeRadTan:
      return "pinhole-radtan";
    case CameraModel::kKannalaBrandt:
      return "kannala-brandt";
  }
  return "unknown";
}

}  // namespace orbatlas
