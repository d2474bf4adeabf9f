#pragma once
// Turns one image of a single camera into a Frame: ORB on the image as it
// comes (no rectification: keypoints keep their detected pixels and get
// bearings through the camera model, distortion included), keypoint geometry
// and the search grid; no stereo depth. For single-camera sessions: those that
// localise in stored maps and those that map (monocular SLAM, docs/monocular.md).
#include <memory>
#include <opencv2/core/mat.hpp>

#include "core/camera/camera.h"
#include "core/features/orb_extractor.h"
#include "core/io/settings.h"
#include "core/tracking/frame.h"
#include "core/tracking/frame_frontend.h"
#include "core/tracking/frame_camera.h"

namespace orbatlas {

class MonoFrontend final : public FrameFrontend {
 public:
  // The settings' first camera (any model the camera factory builds). Throws
  // Error for an unusable calibration.
  explicit MonoFrontend(const SlamSettings& settings);

  // `image`: CV_8UC1 (or 3-channel, converted) of the calibrated size; DataError
  // on an empty image or another size.
  Frame make_frame(TimestampNs t_ns, const cv::Mat& image);
  // The same; `second` must be empty (DataError otherwise: one camera).
  Frame make_frame(TimestampNs t_ns, const cv::Mat& image, const cv::Mat& second) override;

  const Camera& camera() const { return *camera_; }
  const CameraCalibration& calibration() const override { return calibration_; }
  // The camera, no stereo (bf 0) and the ORB scale pyramid (see StereoFrontend).
  FrameCamera frame_camera() const override;
  double baseline() const override { return 0.0; }
  // While a map starts, frames have kStartingFeatureFactor times the features
  // (ORB-SLAM3's initialisation extractor: the two views need many matches).
  void set_map_starting(bool starting) override { starting_ = starting; }
  static constexpr int kStartingFeatureFactor = 5;

 private:
  CameraCalibration calibration_;
  std::unique_ptr<Camera> camera_;
  OrbExtractor extractor_;
  OrbExtractor starting_extractor_;
  bool starting_ = false;
  cv::Mat gray_;
};

// The extractor a single camera uses while its map starts:
// kStartingFeatureFactor times the settings' features.
OrbExtractorOptions starting_orb_options(const SlamSettings& settings);

}  // namespace orbatlas
