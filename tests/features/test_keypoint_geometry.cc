// The camera geometry of keypoints: bearings and undistorted pixels of a
// pinhole camera against OpenCV's undistortion, and a fisheye's rays beyond 90
// degrees, which have no pinhole pixel.
#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <vector>

#include "core/camera/camera_factory.h"
#include "core/features/keypoint_geometry.h"
#include "tests/support/sim_test_helpers.h"

namespace orbatlas {
namespace {

TEST(KeypointGeometry, PinholeMatchesOpenCvUndistortion) {
  const CameraCalibration cal = test::euroc_cam0();
  const auto camera = make_camera(cal);
  std::vector<Keypoint> keypoints;
  std::vector<cv::Point2d> pixels;
  for (const float u : {0.0f, 100.5f, 376.0f, 751.0f})
    for (const float v : {0.0f, 240.0f, 479.0f}) {
      Keypoint kp;
      kp.uv = Eigen::Vector2f(u, v);
      keypoints.push_back(kp);
      pixels.emplace_back(u, v);
    }
  compute_keypoint_geometry(*camera, keypoints);
  const cv::Mat K = (cv::Mat_<double>(3, 3) << cal.fx, 0, cal.cx, 0, cal.fy, cal.cy, 0, 0, 1);
  std::vector<cv::Point2d> undistorted;
  cv::undistortPoints(pixels, undistorted, K, cv::Mat(cal.distortion), cv::noArray(), K,
                      cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100, 1e-12));
  for (std::size_t i = 0; i < keypoints.size(); ++i) {
    const Keypoint& kp = keypoints[i];
    EXPECT_NEAR(kp.bearing.norm(), 1.0, 1e-12);
    Eigen::Vector2d back;
    ASSERT_TRUE(camera->project(kp.bearing, &back));
    EXPECT_NEAR((back - kp.uv.cast<double>()).norm(), 0.0, 1e-3) << kp.uv.transpose();
    EXPECT_NEAR(kp.uv_undistorted.x(), undistorted[i].x, 0.02) << kp.uv.transpose();
    EXPECT_NEAR(kp.uv_undistorted.y(), undistorted[i].y, 0.02) << kp.uv.transpose();
  }
}

TEST(KeypointGeometry, FisheyeBeyondNinetyDegreesHasNoPinholePixel) {
  const CameraCalibration c = test::fisheye_left();  // EuRoC-size Kannala-Brandt
  const auto camera = make_camera(c);
  std::vector<Keypoint> keypoints(2);
  keypoints[0].uv = Eigen::Vector2f(500.0f, 300.0f);
  keypoints[1].uv = Eigen::Vector2f(-1000.0f, 226.0f);  // about 3.8 rad off axis
  compute_keypoint_geometry(*camera, keypoints);
  ASSERT_GT(keypoints[0].bearing.z(), 0.0);
  const Eigen::Vector3d& b = keypoints[0].bearing;
  EXPECT_NEAR(keypoints[0].uv_undistorted.x(), c.fx * b.x() / b.z() + c.cx, 1e-3);
  EXPECT_NEAR(keypoints[0].uv_undistorted.y(), c.fy * b.y() / b.z() + c.cy, 1e-3);
  ASSERT_LE(keypoints[1].bearing.z(), 0.0);
  EXPECT_TRUE(std::isnan(keypoints[1].uv_undistorted.x()));
  EXPECT_TRUE(std::isnan(keypoints[1].uv_undistorted.y()));
}

}  // namespace
}  // namespace orbatlas
