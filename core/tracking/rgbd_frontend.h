#pragma once
// Turns an image and its registered depth image (an RGB-D camera)
// into a Frame, as ORB-SLAM3 does: both images undistorted to a pinhole camera
// of the same intrinsics (the depth by nearest neighbour: depths are not
// averaged across edges), ORB on the image, and each keypoint with a depth
// (its pixel's value / RGBD.DepthMapFactor, nonzero) given a virtual right
// coordinate u - bf / depth with bf = Stereo.b * fx. Tracking, mapping and the
// map then treat it as a stereo keypoint.
#include <opencv2/core/mat.hpp>

#include "core/camera/camera.h"
#include "core/features/orb_extractor.h"
#include "core/tracking/frame_frontend.h"

namespace orbatlas {

class RgbdFrontend final : public FrameFrontend {
 public:
  // rgbd settings with a pinhole camera0. Throws Error otherwise.
  explicit RgbdFrontend(const SlamSettings& settings);

  // `image`: CV_8UC1 (or 3-channel, converted); `depth`: CV_16UC1; both of the
  // calibrated size. DataError otherwise.
  Frame make_frame(TimestampNs t_ns, const cv::Mat& image, const cv::Mat& depth) override;
  FrameCamera frame_camera() const override;
  const CameraCalibration& calibration() const override { return undistorted_; }
  double baseline() const override { return baseline_; }
  double bf() const { return baseline_ * undistorted_.fx; }

 private:
  CameraCalibration undistorted_;
  std::unique_ptr<Camera> camera_;
  double baseline_ = 0.0, depth_factor_ = 0.0;
  cv::Mat map_x_, map_y_;  // undistortion maps (empty when the camera has no distortion)
  OrbExtractor extractor_;
  cv::Mat gray_, gray_rect_, depth_rect_;
};

}  // namespace orbatlas
