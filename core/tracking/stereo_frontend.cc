#include "core/tracking/stereo_frontend.h"

#include <algorithm>
#include <atomic>
#include <future>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "core/camera/camera_factory.h"
#include "core/common/error.h"
#include "core/features/keypoint_geometry.h"
#include "core/tracking/gray_image.h"

namespace orbatlas {
namespace {

const CameraCalibration& require_camera1(const SlamSettings& settings) {
  ORBATLAS_CHECK(settings.camera1.has_value(), "stereo tracking needs a second camera (Camera2.* in the settings)");
  return *settings.camera1;
}

}  // namespace

OrbExtractorOptions orb_options_from(const SlamSettings& settings) {
  OrbExtractorOptions o;
  o.n_features = settings.orb.n_features;
  o.scale_factor = settings.orb.scale_factor;
  o.n_levels = settings.orb.n_levels;
  o.ini_th_fast = settings.orb.ini_th_fast;
  o.min_th_fast = settings.orb.min_th_fast;
  return o;
}

std::size_t Frame::stereo_count() const {
  return static_cast<std::size_t>(std::count_if(depth.begin(), depth.end(), [](float d) { return d > 0.0f; }));
}

StereoFrontend::StereoFrontend(const SlamSettings& settings, bool parallel)
    : rectifier_(settings.camera0, require_camera1(settings)),
      camera_(make_camera(rectifier_.rectified_left())),
      left_extractor_(orb_options_from(settings)),
      right_extractor_(orb_options_from(settings)) {
  if (parallel) right_worker_ = std::make_unique<SerialWorker>(1, 0, "right image");
}

Frame StereoFrontend::make_frame(TimestampNs t_ns, const cv::Mat& left, const cv::Mat& right) {
  const cv::Mat& l = as_gray(left, left_gray_, "left");
  const cv::Mat& r = as_gray(right, right_gray_, "right");
  const CameraCalibration& c0 = rectifier_.rectified_left();
  ORBATLAS_DATA_CHECK(l.cols == c0.width && l.rows == c0.height && r.cols == c0.width && r.rows == c0.height,
                      "stereo pair of " << l.cols << "x" << l.rows << " and " << r.cols << "x" << r.rows
                                        << " pixels; the calibration says " << c0.width << "x" << c0.height);
  // The right image on a second thread (as ORB-SLAM): the two extractions are
  // independent and together are most of a frame's cost. Whichever thread
  // claims the right image first extracts it: when the worker has not started
  // by the time the left image is done (every core busy with other sessions),
  // this thread takes it back, so a frame never waits longer than both images
  // on one thread.
  auto right_side = [&] {
    rectifier_.rectify_right(r, right_rect_);
    return right_extractor_.extract(right_rect_);
  };
  std::future<ImageFeatures> right_job;
  const auto claimed = std::make_shared<std::atomic<bool>>(false);
  if (right_worker_) {
    auto task = std::make_shared<std::packaged_task<ImageFeatures()>>(right_side);
    right_job = task->get_future();
    // (Once this thread has claimed it, the worker drops the task untouched.)
    if (!right_worker_->try_post([task, claimed] {
          if (!claimed->exchange(true)) (*task)();
        }))
      right_job = {};  // busy: done here below
  }
  // True when the worker is extracting (or has extracted) the right image.
  const auto worker_has_it = [&] { return right_job.valid() && claimed->exchange(true); };
  Frame f;
  f.t_ns = t_ns;
  ImageFeatures right_features;
  try {
    rectifier_.rectify_left(l, left_rect_);
    f.features = left_extractor_.extract(left_rect_);
  } catch (...) {
    if (worker_has_it()) right_job.wait();  // never leave the job running on our buffers
    throw;
  }
  ++stereo_frames_;
  if (worker_has_it()) {
    ++right_by_worker_;
    right_features = right_job.get();
  } else {
    right_features = right_side();
  }
  StereoDepths depths =
      match_stereo_rectified(f.features, left_extractor_.pyramid(), right_features, right_extractor_.pyramid(),
                             left_extractor_.scale_factors(), bf(), baseline());
  f.depth = std::move(depths.depth);
  f.u_right = std::move(depths.u_right);
  finish_frame(*camera_, f);
  return f;
}

void StereoFrontend::warm_up() {
  const CameraCalibration& c0 = rectifier_.rectified_left();
  // Blurred noise: corners about as dense as a textured scene's (raw noise
  // would grow the candidate buffers far beyond what real images need).
  cv::Mat noise(c0.height, c0.width, CV_8UC1), left, right;
  cv::RNG rng(0x5eed);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(noise, left, cv::Size(0, 0), 1.5);
  cv::normalize(left, left, 0, 255, cv::NORM_MINMAX);
  // The right image: the left one 8 pixels to the left (a disparity of 8).
  right = cv::Mat(left.size(), CV_8UC1, cv::Scalar(0));
  const int shift = std::min(8, c0.width - 1);
  left.colRange(shift, left.cols).copyTo(right.colRange(0, left.cols - shift));
  const std::size_t frames = stereo_frames_, by_worker = right_by_worker_;
  (void)make_frame(0, left, right);
  stereo_frames_ = frames;
  right_by_worker_ = by_worker;
}

Frame StereoFrontend::make_left_frame(TimestampNs t_ns, const cv::Mat& left) {
  const cv::Mat& l = as_gray(left, left_gray_, "left");
  const CameraCalibration& c0 = rectifier_.rectified_left();
  ORBATLAS_DATA_CHECK(l.cols == c0.width && l.rows == c0.height, "image of " << l.cols << "x" << l.rows
                                                                             << " pixels; the calibration says "
                                                                             << c0.width << "x" << c0.height);
  Frame f;
  f.t_ns = t_ns;
  rectifier_.rectify_left(l, left_rect_);
  f.features = left_extractor_.extract(left_rect_);
  f.depth.assign(f.size(), -1.0f);
  f.u_right.assign(f.size(), -1.0f);
  finish_frame(*camera_, f);
  return f;
}

void finish_frame(const Camera& camera, Frame& f) {
  compute_keypoint_geometry(camera, f.features.keypoints);
  f.grid = FeatureGrid(f.features);
  f.map_points.assign(f.size(), nullptr);
  f.outlier.assign(f.size(), false);
}

FrameCamera make_frame_camera(const Camera& camera, double bf, const OrbExtractor& extractor) {
  FrameCamera cam;
  cam.camera = &camera;
  cam.bf = bf;
  cam.pyramid.scale_factor = extractor.options().scale_factor;
  cam.pyramid.n_levels = extractor.options().n_levels;
  return cam;
}

FrameCamera StereoFrontend::frame_camera() const { return make_frame_camera(*camera_, bf(), left_extractor_); }

}  // namespace orbatlas
