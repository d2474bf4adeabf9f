#pragma once
// Shared fixtures for the simulator tests: the real EuRoC stereo calibration.
#include "core/camera/camera_calibration.h"
#include "core/geometry/pose.h"

namespace orbatlas::test {

inline CameraCalibration euroc_cam0() {
  CameraCalibration c;
  c.model = CameraModel::kPinholeRadTan;
  c.fx = 458.654;
  c.fy = 457.296;
  c.cx = 367.215;
  c.cy = 248.375;
  c.distortion = {-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05};
  c.width = 752;
  c.height = 480;
  c.rate_hz = 20;
  Eigen::Matrix4d m;
  m << 0.0148655429818, -0.999880929698, 0.00414029679422, -0.0216401454975, 0.999557249008, 0.0149672133247,
      0.025715529948, -0.064676986768, -0.0257744366974, 0.00375618835797, 0.999660727178, 0.00981073058949, 0, 0, 0, 1;
  c.T_b_c = Pose3::from_matrix(m);
  return c;
}

inline CameraCalibration euroc_cam1() {
  CameraCalibration c;
  c.model = CameraModel::kPinholeRadTan;
  c.fx = 457.587;
  c.fy = 456.134;
  c.cx = 379.999;
  c.cy = 255.238;
  c.distortion = {-0.28368365, 0.07451284, -0.00010473, -3.55590700e-05};
  c.width = 752;
  c.height = 480;
  c.rate_hz = 20;
  Eigen::Matrix4d m;
  m << 0.0125552670891, -0.999755099723, 0.0182237714554, -0.0198435579556, 0.999598781151, 0.0130119051815,
      0.0251588363115, 0.0453689425024, -0.0253898008918, 0.0179005838253, 0.999517347078, 0.00786212447038, 0, 0, 0, 1;
  c.T_b_c = Pose3::from_matrix(m);
  return c;
}

}  // namespace orbatlas::test

namespace orbatlas::test {

// The fisheye (Kannala-Brandt) stereo rig of ../shared/data/euroc/extra_images/stereo_frame.
inline CameraCalibration fisheye_left() {
  CameraCalibration c;
  c.model = CameraModel::kKannalaBrandt;
  c.fx = 366.163;
  c.fy = 365.631;
  c.cx = 380.573;
  c.cy = 225.950;
  c.distortion = {-0.020476443, -0.007108226, 0.002180580, -0.001192386};
  c.width = 752;
  c.height = 480;
  c.rate_hz = 25;
  Eigen::Matrix4d m;
  m << -0.002506617, -0.999975268, 0.006571120, -0.003087790, 0.999995111, -0.002494275, 0.001885736, 0.001692289,
      -0.001869299, 0.006575815, 0.999976632, -0.000023275, 0, 0, 0, 1;
  c.T_b_c = Pose3::from_matrix(m);
  return c;
}

inline CameraCalibration fisheye_right() {
  CameraCalibration c;
  c.model = CameraModel::kKannalaBrandt;
  c.fx = 367.032;
  c.fy = 366.632;
  c.cx = 379.304;
  c.cy = 236.659;
  c.distortion = {-0.019659843, -0.005079736, -0.001357391, 0.000419038};
  c.width = 752;
  c.height = 480;
  c.rate_hz = 25;
  Eigen::Matrix4d m;
  m << 0.000468892, -0.999992519, 0.003839613, -0.004419063, 0.999987552, 0.000487955, 0.004965573, 0.122004189,
      -0.004967410, 0.003837237, 0.999980300, -0.000145419, 0, 0, 0, 1;
  c.T_b_c = Pose3::from_matrix(m);
  return c;
}

}  // namespace orbatlas::test
