// AtlasService: the requests' settings (named configs or inline text,
// request_settings.h), localisation (LocalizerPool) and the replicas of its
// database it lists.
#include <string>
#include <vector>

#include "core/common/data_paths.h"
#include "core/server/atlas_service.h"
#include "core/server/service_error.h"

namespace orbatlas {

std::filesystem::path AtlasService::config_dir() const {
  return options_.config_dir.empty() ? shipped_config_dir() : options_.config_dir;
}

SensorType AtlasService::request_sensor(const SessionRequest& request) const {
  return orbatlas::request_sensor(request, config_dir());
}

void AtlasService::check_upload(const SessionRequest& request) const { check_upload_request(request, config_dir()); }

LocalizeReply AtlasService::localize(const LocalizeRequest& request) {
  const LocalizeReply reply = localizers_.localize(request);
  metrics_.localized(reply.recognised, reply.ms);
  return reply;
}

cv::Size AtlasService::localize_image_size(const SettingsSource& settings) { return localizers_.image_size(settings); }

std::vector<ReplicaInfo> AtlasService::replicas() const {
  try {
    return replica_->replicas();
  } catch (const std::exception& e) {
    throw ServiceError(ServiceErrorKind::kUnavailable, "database_unavailable",
                       std::string("cannot read the replicas from the atlas's database: ") + e.what());
  }
}

}  // namespace orbatlas
