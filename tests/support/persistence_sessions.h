#pragma once
// What the persistence tests of sessions share: an EuRoC-like camera (its
// focal length and body-to-camera offset moved by `shift`), and two sessions
// compared field by field, their cameras bit for bit.
#include <gtest/gtest.h>

#include <utility>
#include <vector>

#include "core/camera/camera_calibration.h"
#include "core/persistence/session_info.h"
#include "tests/persistence/test_persistence_expect.h"

namespace orbatlas::test {

inline CameraCalibration camera(CameraModel model, std::vector<double> distortion, double shift) {
  CameraCalibration c;
  c.model = model;
  c.fx = 458.654 + shift;
  c.fy = 457.296 + shift;
  c.cx = 367.215;
  c.cy = 248.375;
  c.distortion = std::move(distortion);
  c.width = 752;
  c.height = 480;
  c.rate_hz = 20.0;
  c.T_b_c =
      Pose3(Eigen::Quaterniond(0.7123, -0.0077, 0.0105, 0.7018), Eigen::Vector3d(-0.0216, -0.0647, 0.0098 + shift));
  return c;
}

inline void expect_session_eq(const SessionInfo& a, const SessionInfo& b) {
  EXPECT_EQ(a.id, b.id);
  EXPECT_EQ(a.name, b.name);
  EXPECT_EQ(a.sensor, b.sensor);
  EXPECT_EQ(a.created_ns, b.created_ns);
  ASSERT_EQ(a.cameras.size(), b.cameras.size());
  for (std::size_t i = 0; i < a.cameras.size(); ++i) {
    const CameraCalibration &ca = a.cameras[i], &cb = b.cameras[i];
    EXPECT_EQ(ca.model, cb.model);
    EXPECT_EQ(ca.fx, cb.fx);
    EXPECT_EQ(ca.fy, cb.fy);
    EXPECT_EQ(ca.cx, cb.cx);
    EXPECT_EQ(ca.cy, cb.cy);
    EXPECT_EQ(ca.distortion, cb.distortion);
    EXPECT_EQ(ca.width, cb.width);
    EXPECT_EQ(ca.height, cb.height);
    EXPECT_EQ(ca.rate_hz, cb.rate_hz);
    expect_pose_eq(ca.T_b_c, cb.T_b_c, "T_b_c");
  }
}

}  // namespace orbatlas::test
