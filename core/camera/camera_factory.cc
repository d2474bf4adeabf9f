#include "core/camera/camera_factory.h"

#include <cmath>

#include "core/camera/kannala_brandt.h"
#include "core/camera/pinhole_radtan.h"
#include "core/common/error.h"

namespace orbatlas {

void check_calibration(const CameraCalibration& c) {
  const char* name = camera_model_name(c.model);
  ORBATLAS_CHECK(c.model == CameraModel::kPinholeRadTan || c.model == CameraModel::kKannalaBrandt,
                 "camera calibration: unknown camera model " << static_cast<int>(c.model));
  ORBATLAS_CHECK(std::isfinite(c.fx) && c.fx > 0, name << " camera: fx must be positive, got " << c.fx);
  ORBATLAS_CHECK(std::isfinite(c.fy) && c.fy > 0, name << " camera: fy must be positive, got " << c.fy);
  ORBATLAS_CHECK(std::isfinite(c.cx), name << " camera: cx must be finite, got " << c.cx);
  ORBATLAS_CHECK(std::isfinite(c.cy), name << " camera: cy must be finite, got " << c.cy);
  ORBATLAS_CHECK(c.width > 0 && c.height > 0,
                 name << " camera: image size must be positive, got " << c.width << "x" << c.height);
  if (c.model == CameraModel::kPinholeRadTan) {
    ORBATLAS_CHECK(
        c.distortion.size() == 4 || c.distortion.size() == 5,
        name << " camera: needs 4 or 5 distortion coefficients (k1 k2 p1 p2 [k3]), got " << c.distortion.size());
  } else {
    ORBATLAS_CHECK(c.distortion.size() == 4,
                   name << " camera: needs 4 distortion coefficients (k1 k2 k3 k4), got " << c.distortion.size());
  }
  for (size_t i = 0; i < c.distortion.size(); ++i) {
    ORBATLAS_CHECK(std::isfinite(c.distortion[i]), name << " camera: distortion coefficient " << i << " is not finite");
  }
}

std::unique_ptr<Camera> make_camera(const CameraCalibration& calibration) {
  check_calibration(calibration);
  if (calibration.model == CameraModel::kKannalaBrandt) return std::make_unique<KannalaBrandt>(calibration);
  return std::make_unique<PinholeRadTan>(calibration);
}

}  // namespace orbatlas
