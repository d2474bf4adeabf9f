#pragma once
// What turns a sensor's frame into a Frame for tracking and mapping: a stereo
// pair (StereoFrontend), an image and its registered depth image
// (RgbdFrontend), or one image (MonoFrontend). The first two hand tracking an
// undistorted pinhole camera and a right image coordinate per keypoint with
// depth (real or virtual), so the stereo machinery serves both; the single
// camera gives no depth (bf 0: monocular tracking and mapping).
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
  // While a map is starting (tracking not initialised): a single camera
  // extracts more features then (its map starts from two views' matches).
  virtual void set_map_starting(bool /*starting*/) {}
  // Before the first frame: whatever the first frame of this size would set up
  // (scratch buffers allocated and first touched), so that the first frame
  // costs what the others do. Changes no frame made afterwards.
  virtual void warm_up() {}
};

// A stereo front end for stereo settings, an RGB-D one for rgbd settings, a
// single-camera one for mono and mono_inertial settings: the rectified left
// camera of the rig when the settings still hold a second camera (a stereo
// config used as a single camera), else the camera as it is.
std::unique_ptr<FrameFrontend> make_frame_frontend(const SlamSettings& settings, bool parallel_stereo = true);

}  // namespace orbatlas
