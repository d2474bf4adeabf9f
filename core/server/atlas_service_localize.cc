// AtlasService: single-image localisation against the stored maps
// (/v1/localize), with one front end per configuration kept for the requests.
#include <chrono>
#include <string>

#include "core/relocalization/relocalizer.h"
#include "core/server/atlas_service.h"
#include "core/server/atlas_service_localizer.h"
#include "core/server/service_error.h"

namespace orbatlas {

std::shared_ptr<AtlasService::LocalizerContext> AtlasService::localizer_for(const SettingsSource& source) {
  const std::string key = source.config.empty() ? "yaml:" + source.settings_yaml : "config:" + source.config;
  {
    std::lock_guard lock(localizers_mutex_);
    if (const auto it = localizers_.find(key); it != localizers_.end()) return it->second;
  }
  // Read and built outside the (leaf) lock: a config file on a slow disk holds
  // up no other localisation. Two first requests may both build; one is kept.
  const LoadedSettings loaded = load_settings(source);
  std::shared_ptr<LocalizerContext> context;
  try {
    context = std::make_shared<LocalizerContext>(loaded.settings);
  } catch (const std::exception& e) {
    throw ServiceError(ServiceErrorKind::kBadRequest, "bad_config", std::string("unusable settings: ") + e.what());
  }
  std::lock_guard lock(localizers_mutex_);
  if (const auto it = localizers_.find(key); it != localizers_.end()) return it->second;
  if (localizers_.size() >= kMaxLocalizers) localizers_.erase(localizers_.begin());
  localizers_[key] = context;
  return context;
}

cv::Size AtlasService::localize_image_size(const SettingsSource& settings) {
  const Camera& camera = *localizer_for(settings)->cam.camera;
  return {camera.calibration().width, camera.calibration().height};
}

LocalizeReply AtlasService::localize(const LocalizeRequest& request) {
  const auto start = std::chrono::steady_clock::now();
  if (request.map && !atlas_.map(*request.map)) throw_not_found("no map " + std::to_string(*request.map));
  const std::shared_ptr<LocalizerContext> context = localizer_for(request.settings);
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
  localize_requests_.Increment();
  if (reply.recognised) localize_recognised_.Increment();
  localize_latency_.Observe(reply.ms / 1000.0);
  return reply;
}

}  // namespace orbatlas
