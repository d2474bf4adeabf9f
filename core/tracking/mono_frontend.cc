#include "core/tracking/mono_frontend.h"

#include "core/camera/camera_factory.h"
#include "core/common/error.h"
#include "core/tracking/gray_image.h"
#include "core/tracking/stereo_frontend.h"

namespace orbatlas {

MonoFrontend::MonoFrontend(const SlamSettings& settings)
    : calibration_(settings.camera0),
      camera_(make_camera(settings.camera0)),
      extractor_(orb_options_from(settings)),
      starting_extractor_(starting_orb_options(settings)) {}

Frame MonoFrontend::make_frame(TimestampNs t_ns, const cv::Mat& image) {
  const cv::Mat& gray = as_gray(image, gray_, "camera");
  ORBATLAS_DATA_CHECK(gray.cols == calibration_.width && gray.rows == calibration_.height,
                      "image of " << gray.cols << "x" << gray.rows << " pixels; the calibration says "
                                  << calibration_.width << "x" << calibration_.height);
  Frame f;
  f.t_ns = t_ns;
  f.features = (starting_ ? starting_extractor_ : extractor_).extract(gray);
  f.depth.assign(f.size(), -1.0f);
  f.u_right.assign(f.size(), -1.0f);
  finish_frame(*camera_, f);
  return f;
}

Frame MonoFrontend::make_frame(TimestampNs t_ns, const cv::Mat& image, const cv::Mat& second) {
  ORBATLAS_DATA_CHECK(second.empty(), "a single-camera session takes one image per frame, not two");
  return make_frame(t_ns, image);
}

OrbExtractorOptions starting_orb_options(const SlamSettings& settings) {
  OrbExtractorOptions o = orb_options_from(settings);
  o.n_features *= MonoFrontend::kStartingFeatureFactor;
  return o;
}

FrameCamera MonoFrontend::frame_camera() const { return make_frame_camera(*camera_, 0.0, extractor_); }

}  // namespace orbatlas
