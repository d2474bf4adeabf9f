#pragma once
// What turns a sensor's frame into a Frame for tracking and mapping, whatever
// the sensor gives depth with: a stereo pair (StereoFrontend) or an image and
// its registered depth image (RgbdFrontend). Both hand tracking an undistorted
// pinhole camera and a right image coordinate per keypoint with depth (real or
// virtual), so the stereo machinery serves both.
#include <memory>
#include <opencv2/core/mat.hpp>

#include "core/camera/camera_calibration.h"
#include "core/io/settings.h"
#include "core/tracking/frame.h"
#include "core/tracking/frame_camera.h"

namespace orbatlas {

class FrameFrontend {
 public:
  virtual ~FrameFrontend() = default;
  // `image`: the (left) image; `second`: the right image, or the depth image
  // registered to `image`. DataError on images this sensor cannot take.
  virtual Frame make_frame(TimestampNs t_ns, const cv::Mat& image, const cv::Mat& second) = 0;
  // The camera tracking works with (pinhole, no distortion), bf and the pyramid.
  virtual FrameCamera frame_camera() const = 0;
  virtual const CameraCalibration& calibration() const = 0;
  virtual double baseline() const = 0;  // metres (the RGB-D sensor's virtual one)
};

// A stereo front end for stereo settings, an RGB-D one for rgbd settings;
// Error for the others (a single camera has no depth).
std::unique_ptr<FrameFrontend> make_frame_frontend(const SlamSettings& settings);

}  // namespace orbatlas
