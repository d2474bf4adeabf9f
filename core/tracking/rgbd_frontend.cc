#include "core/tracking/rgbd_frontend.h"

#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "core/camera/camera_factory.h"
#include "core/common/error.h"
#include "core/tracking/gray_image.h"
#include "core/tracking/mono_frontend.h"
#include "core/tracking/stereo_left_frontend.h"
#include "core/tracking/stereo_frontend.h"

namespace orbatlas {
namespace {

const SlamSettings& require_rgbd(const SlamSettings& settings) {
  ORBATLAS_CHECK(settings.is_rgbd() && settings.rgbd.has_value(),
                 "RGB-D tracking needs rgbd settings (RGBD.DepthMapFactor, Stereo.b)");
  ORBATLAS_CHECK(settings.camera0.model == CameraModel::kPinholeRadTan,
                 "RGB-D tracking needs a pinhole camera (Camera.type: \"PinHole\")");
  return settings;
}

}  // namespace

RgbdFrontend::RgbdFrontend(const SlamSettings& settings)
    : undistorted_(require_rgbd(settings).camera0),
      baseline_(settings.rgbd->baseline_m),
      depth_factor_(settings.rgbd->depth_map_factor),
      extractor_(orb_options_from(settings)) {
  const CameraCalibration& c = settings.camera0;
  const bool distorted = std::any_of(c.distortion.begin(), c.distortion.end(), [](double d) { return d != 0.0; });
  undistorted_.distortion.assign(c.distortion.size(), 0.0);
  if (distorted) {
    const cv::Matx33d K(c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1);
    cv::initUndistortRectifyMap(K, cv::Mat(c.distortion), cv::Matx33d::eye(), K, cv::Size(c.width, c.height), CV_32FC1,
                                map_x_, map_y_);
  }
  camera_ = make_camera(undistorted_);
}

Frame RgbdFrontend::make_frame(TimestampNs t_ns, const cv::Mat& image, const cv::Mat& depth) {
  const cv::Mat& g = as_gray(image, gray_, "image");
  const CameraCalibration& c = undistorted_;
  ORBATLAS_DATA_CHECK(g.cols == c.width && g.rows == c.height, "image of " << g.cols << "x" << g.rows
                                                                           << " pixels; the calibration says "
                                                                           << c.width << "x" << c.height);
  ORBATLAS_DATA_CHECK(!depth.empty(), "an RGB-D frame needs its depth image");
  ORBATLAS_DATA_CHECK(depth.type() == CV_16UC1, "the depth image must be 16-bit single-channel (TUM RGB-D)");
  ORBATLAS_DATA_CHECK(
      depth.cols == c.width && depth.rows == c.height,
      "depth image of " << depth.cols << "x" << depth.rows << " pixels; the image's is " << c.width << "x" << c.height);
  if (map_x_.empty()) {
    gray_rect_ = g;
    depth_rect_ = depth;
  } else {
    cv::remap(g, gray_rect_, map_x_, map_y_, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
    cv::remap(depth, depth_rect_, map_x_, map_y_, cv::INTER_NEAREST, cv::BORDER_CONSTANT, cv::Scalar(0));
  }
  Frame f;
  f.t_ns = t_ns;
  f.features = extractor_.extract(gray_rect_);
  f.depth.assign(f.size(), -1.0f);
  f.u_right.assign(f.size(), -1.0f);
  const double bf_px = bf();
  for (std::size_t i = 0; i < f.size(); ++i) {
    const Eigen::Vector2f& uv = f.features.keypoints[i].uv;
    const int u = static_cast<int>(std::lround(uv.x())), v = static_cast<int>(std::lround(uv.y()));
    if (u < 0 || v < 0 || u >= depth_rect_.cols || v >= depth_rect_.rows) continue;
    const std::uint16_t value = depth_rect_.at<std::uint16_t>(v, u);
    if (value == 0) continue;
    const double d = value / depth_factor_;
    f.depth[i] = static_cast<float>(d);
    f.u_right[i] = static_cast<float>(uv.x() - bf_px / d);
  }
  finish_frame(*camera_, f);
  return f;
}

FrameCamera RgbdFrontend::frame_camera() const { return make_frame_camera(*camera_, bf(), extractor_); }

std::unique_ptr<FrameFrontend> make_frame_frontend(const SlamSettings& settings, bool parallel_stereo) {
  if (settings.is_rgbd()) return std::make_unique<RgbdFrontend>(settings);
  if (settings.sensor == SensorType::kMonocular || settings.sensor == SensorType::kMonocularInertial) {
    // The left camera of a stereo rig: rectified as the rig's stereo maps are.
    if (settings.camera1) return std::make_unique<StereoLeftFrontend>(settings);
    return std::make_unique<MonoFrontend>(settings);
  }
  ORBATLAS_CHECK(settings.is_stereo(), "no front end for sensor " << sensor_type_name(settings.sensor));
  return std::make_unique<StereoFrontend>(settings, parallel_stereo);
}

}  // namespace orbatlas
