#pragma once
// Turns a raw stereo pair into a Frame: rectification (pinhole pairs), ORB
// on both images, stereo matching, keypoint geometry and the search grid. One
// frontend per session: it owns the extractors' scratch buffers.
#include <cstddef>
#include <memory>
#include <opencv2/core/mat.hpp>

#include "core/camera/camera.h"
#include "core/common/serial_worker.h"
#include "core/features/orb_extractor.h"
#include "core/features/stereo_rectified.h"
#include "core/io/settings.h"
#include "core/tracking/frame.h"
#include "core/tracking/frame_camera.h"
#include "core/tracking/frame_frontend.h"

namespace orbatlas {

class StereoFrontend final : public FrameFrontend {
 public:
  // Needs a stereo pinhole calibration (camera0 and camera1). Throws Error otherwise.
  // parallel: extract the right image's features on a second thread (one
  // thread for the front end's life, not one per frame: OpenCV keeps per-thread
  // data for every thread that ever ran its parallel code, so a thread per
  // frame grew a long-running server's memory with every frame).
  explicit StereoFrontend(const SlamSettings& settings, bool parallel = true);

  // left/right: CV_8UC1 (or 3-channel, converted) of the calibrated size; throws
  // Error on empty images or a size that does not match the calibration.
  Frame make_frame(TimestampNs t_ns, const cv::Mat& left, const cv::Mat& right) override;
  // The left image alone (relocalising a single image): no stereo depth, every
  // keypoint a bearing only. Same checks as make_frame.
  Frame make_left_frame(TimestampNs t_ns, const cv::Mat& left);
  // One stereo pair of textured images of the calibrated size through
  // make_frame, not counted in stereo_frames(): the extractors' pyramids, FAST
  // scores, cells and quadtree buffers, the rectified images and the right
  // image's thread are set up and touched here. The first real pair otherwise
  // took 12.6 ms of extraction for the left image against 2.7 for the next
  // (measured, clean MH_01), and 46-65 ms of make_frame each when five
  // sessions started at once (docs/benchmarks.md).
  void warm_up() override;

  // The rectified left camera tracking works with (pinhole, no distortion), its
  // pose in the body, and stereo constants.
  const Camera& camera() const { return *camera_; }
  const CameraCalibration& calibration() const override { return rectifier_.rectified_left(); }
  double bf() const { return rectifier_.bf(); }
  double baseline() const override { return rectifier_.baseline(); }
  const OrbExtractor& extractor() const { return left_extractor_; }
  // What tracking and mapping work with: the rectified camera, bf and the ORB
  // scale pyramid (the camera is this front end's: it must outlive the result).
  FrameCamera frame_camera() const override;
  // Stereo pairs made so far, and how many of their right images the second
  // thread extracted (the rest were done on the caller's thread: serial, the
  // worker busy, or not started by the time the left image was done).
  std::size_t stereo_frames() const { return stereo_frames_; }
  std::size_t right_images_on_worker() const { return right_by_worker_; }

 private:
  StereoRectifier rectifier_;
  std::unique_ptr<Camera> camera_;
  OrbExtractor left_extractor_, right_extractor_;
  cv::Mat left_rect_, right_rect_, left_gray_, right_gray_;
  std::size_t stereo_frames_ = 0, right_by_worker_ = 0;
  std::unique_ptr<SerialWorker> right_worker_;  // when parallel; last: stopped before the buffers go
};

OrbExtractorOptions orb_options_from(const SlamSettings& settings);

// What tracking and mapping work with, for a front end's camera, bf (0: no
// depth) and extractor (its ORB scale pyramid).
FrameCamera make_frame_camera(const Camera& camera, double bf, const OrbExtractor& extractor);

// The last step of every front end, once features (and depths) are in:
// keypoint bearings through `camera`, the search grid, empty associations.
void finish_frame(const Camera& camera, Frame& frame);

}  // namespace orbatlas
