#include "core/server/localizer_pool.h"

#include <chrono>

#include "core/common/error.h"
#include "core/relocalization/relocalizer.h"
#include "core/server/service_error.h"
#include "core/tracking/mono_frontend.h"
#include "core/tracking/rgbd_frontend.h"
#include "core/tracking/stereo_frontend.h"

namespace orbatlas {

// A stereo rig localises a pair or its left image; a single camera one image.
// An RGB-D camera localises one image; its maps' keyframes are of the
// undistorted camera its depth front end tracks with (map_cam).
struct LocalizerPool::FrontEnd {
  explicit FrontEnd(const SlamSettings& settings) {
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
  std::mutex mutex;  // one request at a time (scratch buffers)
  std::optional<StereoFrontend> stereo;
  std::optional<MonoFrontend> mono;
  std::optional<RgbdFrontend> rgbd;
  FrameCamera cam, map_cam;
  Pose3 T_b_c;
};

LocalizerPool::LocalizerPool(Atlas& atlas, const Vocabulary& vocabulary, LoadSettings load)
    : atlas_(atlas), vocabulary_(vocabulary), load_(std::move(load)) {
  ORBATLAS_CHECK(load_ != nullptr, "a localizer pool needs a settings reader");
}

LocalizerPool::~LocalizerPool() = default;

std::shared_ptr<LocalizerPool::FrontEnd> LocalizerPool::front_end(const SettingsSource& source) {
  const std::string key = source.config.empty() ? "yaml:" + source.settings_yaml : "config:" + source.config;
  {
    std::lock_guard lock(mutex_);
    if (const auto it = front_ends_.find(key); it != front_ends_.end()) return it->second;
  }
  // Read and built outside the lock: a config file on a slow disk holds up no
  // other localisation. Two first requests may both build; one is kept.
  const LoadedSettings loaded = load_(source);
  std::shared_ptr<FrontEnd> made;
  try {
    made = std::make_shared<FrontEnd>(loaded.settings);
  } catch (const std::exception& e) {
    throw ServiceError(ServiceErrorKind::kBadRequest, "bad_config", std::string("unusable settings: ") + e.what());
  }
  std::lock_guard lock(mutex_);
  if (const auto it = front_ends_.find(key); it != front_ends_.end()) return it->second;
  if (front_ends_.size() >= kMaxLocalizers) front_ends_.erase(front_ends_.begin());
  front_ends_[key] = made;
  return made;
}

cv::Size LocalizerPool::image_size(const SettingsSource& settings) {
  const Camera& camera = *front_end(settings)->cam.camera;
  return {camera.calibration().width, camera.calibration().height};
}

std::shared_ptr<const FrameCamera> LocalizerPool::map_camera(const SettingsSource& settings) {
  const std::shared_ptr<FrontEnd> made = front_end(settings);
  return std::shared_ptr<const FrameCamera>(made, &made->map_cam);
}

std::size_t LocalizerPool::size() const {
  std::lock_guard lock(mutex_);
  return front_ends_.size();
}

LocalizeReply LocalizerPool::localize(const LocalizeRequest& request) {
  const auto start = std::chrono::steady_clock::now();
  if (request.map && !atlas_.map(*request.map)) throw_not_found("no map " + std::to_string(*request.map));
  const std::shared_ptr<FrontEnd> context = front_end(request.settings);
  LocalizeReply reply;
  {
    std::lock_guard lock(context->mutex);
    Frame frame = context->make_frame(request.left, request.right);
    RelocalizationOptions options;
    options.only_map = request.map;
    // No merge half-way through while the maps are read (a merge moves a map's
    // keyframes and points into another's frame): one waits for the other.
    const auto whole = atlas_.lock_maps_shared();
    const RelocalizationResult r =
        relocalize(frame, vocabulary_, atlas_.keyframe_index(), context->cam, context->T_b_c, options);
    reply.recognised = r.success;
    reply.map = r.map;
    reply.T_w_b = r.T_w_b;
    reply.inliers = r.inliers;
    reply.candidates = r.candidates;
  }
  reply.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return reply;
}

}  // namespace orbatlas
