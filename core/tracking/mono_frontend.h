#pragma once
// Turns one image of a single camera into a Frame: ORB on the image as it
// comes (no rectification: keypoints keep their detected pixels and get
// bearings through the camera model, distortion included), keypoint geometry
// and the search grid; no stereo depth. For single-camera sessions that
// localise in stored maps (docs/tracking.md).
#include <memory>
#include <opencv2/core/mat.hpp>

#include "core/camera/camera.h"
#include "core/features/orb_extractor.h"
#include "core/io/settings.h"
#include "core/tracking/frame.h"
#include "core/tracking/frame_camera.h"

namespace orbatlas {

class MonoFrontend {
 public:
  // The settings' first camera (any model the camera factory builds). Throws
  // Error for an unusable calibration.
  explicit MonoFrontend(const SlamSettings& settings);

  // `image`: CV_8UC1 (or 3-channel, converted) of the calibrated size; DataError
  // on an empty image or another size.
  Frame make_frame(TimestampNs t_ns, const cv::Mat& image);

  const Camera& camera() const { return *camera_; }
  const CameraCalibration& calibration() const { return calibration_; }
  // The camera, no stereo (bf 0) and the ORB scale pyramid (see StereoFrontend).
  FrameCamera frame_camera() const;

 private:
  CameraCalibration calibration_;
  std::unique_ptr<Camera> camera_;
  OrbExtractor extractor_;
  cv::Mat gray_;
};

}  // namespace orbatlas
