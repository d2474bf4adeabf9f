#pragma once
// The left camera of a stereo rig used alone (a monocular session of a stereo
// config): the left image is rectified as the stereo front end does, so its
// keypoints and camera are those of the rig's stereo maps (the same pinhole
// and body pose: keyframes of both can be matched, adjusted and merged
// together), but there is no right image and no depth. A monocular map made
// with it that meets one of the rig's stereo maps takes that map's metric
// scale when merged (docs/monocular.md).
#include <memory>
#include <opencv2/core/mat.hpp>

#include "core/camera/camera.h"
#include "core/features/orb_extractor.h"
#include "core/features/stereo_rectified.h"
#include "core/io/settings.h"
#include "core/tracking/frame.h"
#include "core/tracking/frame_frontend.h"
#include "core/tracking/frame_camera.h"

namespace orbatlas {

class StereoLeftFrontend final : public FrameFrontend {
 public:
  // Needs the rig's two cameras (camera0, camera1; pinhole). Throws Error otherwise.
  explicit StereoLeftFrontend(const SlamSettings& settings);

  // `image`: the left image, CV_8UC1 (or 3-channel, converted) of the
  // calibrated size; `second` must be empty. DataError otherwise.
  Frame make_frame(TimestampNs t_ns, const cv::Mat& image, const cv::Mat& second) override;

  // The rectified left camera (its T_b_c includes the rectifying rotation), bf 0.
  const CameraCalibration& calibration() const override { return rectifier_.rectified_left(); }
  FrameCamera frame_camera() const override;
  double baseline() const override { return 0.0; }
  // More features while a map starts from two views (as MonoFrontend).
  void set_map_starting(bool starting) override { starting_ = starting; }

 private:
  StereoRectifier rectifier_;
  std::unique_ptr<Camera> camera_;
  OrbExtractor extractor_;
  OrbExtractor starting_extractor_;
  bool starting_ = false;
  cv::Mat gray_, rectified_;
};

}  // namespace orbatlas
