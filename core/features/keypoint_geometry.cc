#include "core/features/keypoint_geometry.h"

#include <limits>

namespace orbatlas {

void compute_keypoint_geometry(const Camera& camera, std::vector<Keypoint>& keypoints) {
  const CameraCalibration c = camera.calibration();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (Keypoint& kp : keypoints) {
    kp.bearing = camera.unproject(kp.uv.cast<double>());
    const Eigen::Vector3d& b = kp.bearing;
    if (b.z() > 0.0)
      kp.uv_undistorted = Eigen::Vector2f(static_cast<float>(c.fx * b.x() / b.z() + c.cx),
                                          static_cast<float>(c.fy * b.y() / b.z() + c.cy));
    else
      kp.uv_undistorted = Eigen::Vector2f(nan, nan);
  }
}

}  // namespace orbatlas
