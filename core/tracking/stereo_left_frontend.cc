#include "core/tracking/stereo_left_frontend.h"

#include "core/camera/camera_factory.h"
#include "core/common/error.h"
#include "core/tracking/gray_image.h"
#include "core/tracking/mono_frontend.h"
#include "core/tracking/stereo_frontend.h"

namespace orbatlas {
namespace {

const CameraCalibration& require_camera1(const SlamSettings& settings) {
  ORBATLAS_CHECK(settings.camera1.has_value(), "the left camera of a stereo rig needs the rig (Camera2.* missing)");
  return *settings.camera1;
}

}  // namespace

StereoLeftFrontend::StereoLeftFrontend(const SlamSettings& settings)
    : rectifier_(settings.camera0, require_camera1(settings)),
      camera_(make_camera(rectifier_.rectified_left())),
      extractor_(orb_options_from(settings)),
      starting_extractor_(starting_orb_options(settings)) {}

Frame StereoLeftFrontend::make_frame(TimestampNs t_ns, const cv::Mat& image, const cv::Mat& second) {
  ORBATLAS_DATA_CHECK(second.empty(), "a single-camera session takes one image per frame, not two");
  const cv::Mat& gray = as_gray(image, gray_, "camera");
  const CameraCalibration& c = rectifier_.rectified_left();
  ORBATLAS_DATA_CHECK(gray.cols == c.width && gray.rows == c.height, "image of " << gray.cols << "x" << gray.rows
                                                                                 << " pixels; the calibration says "
                                                                                 << c.width << "x" << c.height);
  Frame f;
  f.t_ns = t_ns;
  rectifier_.rectify_left(gray, rectified_);
  f.features = (starting_ ? starting_extractor_ : extractor_).extract(rectified_);
  f.depth.assign(f.size(), -1.0f);
  f.u_right.assign(f.size(), -1.0f);
  finish_frame(*camera_, f);
  return f;
}

FrameCamera StereoLeftFrontend::frame_camera() const { return make_frame_camera(*camera_, 0.0, extractor_); }

}  // namespace orbatlas
