#pragma once
// Single-image localisation against the stored maps (POST /v1/localize): one
// front end per configuration seen (at most kMaxLocalizers; inline settings
// vary, so the oldest is dropped and a request still using it keeps it alive),
// and the camera map merging works with for a configuration. Thread-safe: a
// front end serves one request at a time (its scratch buffers), different
// configurations run at once; the pool's own lock is a leaf.
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include <opencv2/core.hpp>

#include "core/common/ids.h"
#include "core/geometry/pose.h"
#include "core/map/atlas.h"
#include "core/server/request_settings.h"
#include "core/tracking/frame_camera.h"
#include "core/vocabulary/vocabulary.h"

namespace orbatlas {

struct LocalizeRequest {
  SettingsSource settings;
  cv::Mat left, right;  // right may be empty: a single image
  std::optional<MapId> map;
};

struct LocalizeReply {
  bool recognised = false;
  MapId map = 0;
  Pose3 T_w_b;
  int inliers = 0;
  std::size_t candidates = 0;
  double ms = 0.0;
};

class LocalizerPool {
 public:
  static constexpr std::size_t kMaxLocalizers = 8;
  // Reads a request's settings (ServiceError for unusable ones).
  using LoadSettings = std::function<LoadedSettings(const SettingsSource&)>;

  LocalizerPool(Atlas& atlas, const Vocabulary& vocabulary, LoadSettings load);
  ~LocalizerPool();
  LocalizerPool(const LocalizerPool&) = delete;
  LocalizerPool& operator=(const LocalizerPool&) = delete;

  // ServiceError 404 for a map the atlas does not have; DataError for images
  // that do not fit the settings (a pair for a single camera).
  LocalizeReply localize(const LocalizeRequest& request);
  // The image size a localisation with these settings takes: requests are
  // checked against it before their images are decoded.
  cv::Size image_size(const SettingsSource& settings);
  // The camera of the maps made with these settings (an RGB-D camera's is
  // the undistorted one its depth front end tracks with): what merging them
  // works with. It shares its front end's lifetime.
  std::shared_ptr<const FrameCamera> map_camera(const SettingsSource& settings);
  std::size_t size() const;  // front ends kept

 private:
  struct FrontEnd;
  std::shared_ptr<FrontEnd> front_end(const SettingsSource& source);

  Atlas& atlas_;
  const Vocabulary& vocabulary_;
  const LoadSettings load_;
  mutable std::mutex mutex_;  // guards front_ends_; a leaf
  std::map<std::string, std::shared_ptr<FrontEnd>> front_ends_;
};

}  // namespace orbatlas
