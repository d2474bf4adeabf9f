#pragma once
// AtlasService's per-configuration front ends for single-image localisation
// and the cameras map merging works with (private to core/server's
// atlas_service*.cc).
#include <mutex>
#include <optional>

#include "core/server/atlas_service.h"
#include "core/tracking/mono_frontend.h"
#include "core/tracking/rgbd_frontend.h"
#include "core/tracking/stereo_frontend.h"

namespace orbatlas {

struct AtlasService::LocalizerContext {
  // A stereo rig localises a pair or its left image; a single camera one image.
  // An RGB-D camera localises one image; its maps' keyframes are of the
  // undistorted camera its depth front end tracks with (map_cam: what merging
  // the maps works with).
  explicit LocalizerContext(const SlamSettings& settings) {
    if (settings.is_stereo()) {
      stereo.emplace(settings, false);
      cam = stereo->frame_camera();
      T_b_c = stereo->calibration().T_b_c;
    } else {
      mono.emplace(settings);
      cam = mono->frame_camera();
      T_b_c = mono->calibration().T_b_c;
    }
    map_cam = cam;
    if (settings.is_rgbd()) {
      rgbd.emplace(settings);
      map_cam = rgbd->frame_camera();
    }
  }
  Frame make_frame(const cv::Mat& left, const cv::Mat& right) {
    if (mono) {
      ORBATLAS_DATA_CHECK(right.empty(), "the config is a single camera: send one image, not a pair");
      return mono->make_frame(0, left);
    }
    return right.empty() ? stereo->make_left_frame(0, left) : stereo->make_frame(0, left, right);
  }
  std::mutex mutex;  // a frontend has scratch buffers: one request at a time per configuration
  std::optional<StereoFrontend> stereo;
  std::optional<MonoFrontend> mono;
  std::optional<RgbdFrontend> rgbd;
  FrameCamera cam, map_cam;
  Pose3 T_b_c;
};

}  // namespace orbatlas
