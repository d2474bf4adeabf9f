// The settings a request names (a shipped or configured config, or YAML text)
// and the checks of an upload's sensor against them.
#include <filesystem>
#include <regex>
#include <string>

#include "core/common/data_paths.h"
#include "core/server/request_settings.h"
#include "core/server/service_error.h"
#include "core/persistence/map_rigs.h"
#include "core/server/session_rules.h"

namespace orbatlas {

namespace fs = std::filesystem;

LoadedSettings load_request_settings(const SettingsSource& source, const fs::path& config_dir) {
  if (!source.config.empty() && !source.settings_yaml.empty())
    throw_bad_request("give either 'config' or 'settings_yaml', not both");
  if (source.config.empty() && source.settings_yaml.empty())
    throw_bad_request("a configuration is needed: 'config' (a name such as \"euroc/stereo\") or 'settings_yaml'");
  try {
    if (!source.config.empty()) {
      static const std::regex kName("[A-Za-z0-9_\\-]+(/[A-Za-z0-9_\\-]+)*");
      if (!std::regex_match(source.config, kName))
        throw_bad_request("config name '" + source.config + "' is not of the form \"euroc/stereo\"");
      const fs::path file = config_dir / (source.config + ".yaml");
      if (!fs::is_regular_file(file)) throw_not_found("no config named '" + source.config + "'");
      try {
        return {read_settings(file), source.config};
      } catch (const std::exception& e) {
        // Named by the config, not by the server's file path.
        std::string message = e.what();
        if (const auto at = message.find(file.string()); at != std::string::npos)
          message.replace(at, file.string().size(), "config '" + source.config + "'");
        throw ServiceError(ServiceErrorKind::kBadRequest, "bad_config", "unusable settings: " + message);
      }
    }
    // Parsed in memory: no file is written for a request's text.
    ORBATLAS_DATA_CHECK(source.settings_yaml.size() <= kMaxSettingsBytes,
                        "settings_yaml has " << source.settings_yaml.size() << " bytes; at most " << kMaxSettingsBytes);
    return {read_settings_text(source.settings_yaml, "settings_yaml"), "inline"};
  } catch (const ServiceError&) {
    throw;
  } catch (const std::exception& e) {
    throw ServiceError(ServiceErrorKind::kBadRequest, "bad_config", std::string("unusable settings: ") + e.what());
  }
}

SensorType request_sensor(const SessionRequest& request, const fs::path& config_dir) {
  const LoadedSettings loaded = load_request_settings(request.settings, config_dir);
  return session_sensor(request.sensor, loaded.settings);
}

void check_upload_request(const SessionRequest& request, const fs::path& config_dir) {
  check_session_name(request.name);
  // No settings: the recording's own, known once it is extracted (UploadJobs).
  if (request.settings.config.empty() && request.settings.settings_yaml.empty()) {
    if (!request.sensor.empty() && request.sensor != "stereo")
      throw ServiceError(ServiceErrorKind::kBadRequest, "bad_config",
                         "sensor '" + request.sensor + "' needs a config; without one an upload is stereo");
    session_mode(request.mode, SensorType::kStereo, SlamSettings{});  // 400 for an unknown one
    return;
  }
  const LoadedSettings loaded = load_request_settings(request.settings, config_dir);
  const SensorType sensor = session_sensor(request.sensor, loaded.settings);
  const SessionMode mode = session_mode(request.mode, sensor, loaded.settings);  // 400 for an unknown one
  if (sensor == SensorType::kRgbd || loaded.settings.is_rgbd()) {
    if (sensor != SensorType::kRgbd || !loaded.settings.is_rgbd())
      throw ServiceError(ServiceErrorKind::kBadRequest, "bad_config",
                         "sensor '" + std::string(sensor_type_name(sensor)) + "' with config '" + loaded.label +
                             "': an RGB-D recording needs an rgbd config and the reverse");
    return;  // a TUM RGB-D recording, mapped as an rgbd session
  }
  if (is_single_camera(sensor)) {
    if (mode != SessionMode::kMap)
      throw ServiceError(ServiceErrorKind::kUnprocessable, "unsupported_sensor",
                         "uploads are mapped; this single camera only localises in stored maps (stream it as a "
                         "session, or upload it with a mono config to map it)");
    return;  // cam0 of an ASL recording, mapped as a monocular session
  }
  if (!loaded.settings.is_stereo())
    throw ServiceError(ServiceErrorKind::kBadRequest, "bad_config",
                       "config '" + loaded.label + "' is not a stereo rig (Camera2.* missing)");
}

}  // namespace orbatlas
