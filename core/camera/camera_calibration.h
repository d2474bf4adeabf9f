#pragma once
// Calibration of one camera as read from an EuRoC sensor.yaml or an ORB-SLAM3
// settings file: the model, its parameters, the image size and its pose in the body.
#include <string>
#include <vector>

#include "core/geometry/pose.h"

namespace orbatlas {

enum class CameraModel {
  kPinholeRadTan,  // pinhole + radial-tangential (k1, k2, p1, p2[, k3])
  kKannalaBrandt,  // equidistant fisheye (k1..k4); EuRoC's "equidistant", ORB-SLAM3's "KannalaBrandt8"
};

struct CameraCalibration {
  CameraModel model = CameraModel::kPinholeRadTan;
  double fx = 0, fy = 0, cx = 0, cy = 0;
  // kPinholeRadTan: {k1, k2, p1, p2} or {k1, k2, p1, p2, k3}; kKannalaBrandt: {k1, k2, k3, k4}.
  std::vector<double> distortion;
  int width = 0, height = 0;
  double rate_hz = 0;
  Pose3 T_b_c;  // camera in the body (IMU) frame
};

const char* camera_model_name(CameraModel model);

}  // namespace orbatlas
