#pragma once
// The settings a request names: a config of the server's config folder
// ("euroc/stereo" is <config_dir>/euroc/stereo.yaml) or the text of a settings
// file sent inline; and the checks an upload's sensor and mode get against
// them before its body is received. ServiceError for what cannot be used
// (400 a bad name or unusable settings, 404 an unknown config, 422 a single
// camera that would only localise).
#include <filesystem>
#include <string>

#include "core/io/settings.h"
#include "core/server/session_request.h"

namespace orbatlas {

// Request limits checked at the edge (400 beyond them).
inline constexpr std::size_t kMaxSettingsBytes = 1 << 20;  // a settings_yaml text

struct LoadedSettings {
  SlamSettings settings;
  std::string label;  // the config name, or "inline"
};

LoadedSettings load_request_settings(const SettingsSource& source, const std::filesystem::path& config_dir);

// The sensor a request's session has (its recording: the TUM RGB-D layout
// for rgbd, cam0 of an ASL folder for a single camera, else stereo pairs).
SensorType request_sensor(const SessionRequest& request, const std::filesystem::path& config_dir);

// Uploads run sessions that map (stereo, RGB-D, or a single camera with a
// mono config). Without settings the recording's own decide (UploadJobs).
void check_upload_request(const SessionRequest& request, const std::filesystem::path& config_dir);

}  // namespace orbatlas
