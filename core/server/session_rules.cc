#include "core/server/session_rules.h"

#include <cmath>
#include <cstdint>

#include "core/features/stereo_rectified.h"
#include "core/persistence/map_rigs.h"
#include "core/server/service_error.h"

namespace orbatlas {
namespace {

// Valid UTF-8 (no overlong forms or surrogates), no control characters.
bool is_printable_utf8(const std::string& text) {
  for (std::size_t i = 0; i < text.size();) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c < 0x80) {
      if (c < 0x20 || c == 0x7f) return false;
      ++i;
      continue;
    }
    const int extra = (c & 0xe0) == 0xc0 ? 1 : (c & 0xf0) == 0xe0 ? 2 : (c & 0xf8) == 0xf0 ? 3 : -1;
    if (extra < 0 || i + static_cast<std::size_t>(extra) >= text.size()) return false;
    std::uint32_t code = c & (0x3f >> extra);
    for (int k = 1; k <= extra; ++k) {
      const auto next = static_cast<unsigned char>(text[i + k]);
      if ((next & 0xc0) != 0x80) return false;
      code = (code << 6) | (next & 0x3f);
    }
    const std::uint32_t smallest[] = {0, 0x80, 0x800, 0x10000};
    if (code < smallest[extra] || code > 0x10ffff || (code >= 0xd800 && code <= 0xdfff) ||
        (code >= 0x80 && code < 0xa0))
      return false;
    i += 1 + extra;
  }
  return true;
}

}  // namespace

void check_session_name(const std::string& name) {
  if (name.size() > kMaxSessionNameBytes)
    throw_bad_request("a session name has at most " + std::to_string(kMaxSessionNameBytes) + " bytes, got " +
                      std::to_string(name.size()));
  if (!is_printable_utf8(name)) throw_bad_request("a session name must be UTF-8 text without control characters");
}

SensorType session_sensor(const std::string& sensor, const SlamSettings& settings) {
  if (sensor.empty()) return settings.sensor;
  const auto parsed = parse_sensor_type(sensor);
  if (!parsed)
    throw_bad_request("unknown sensor '" + sensor + "' (stereo, stereo_inertial, mono, mono_inertial, rgbd)");
  return *parsed;
}

SessionMode session_mode(const std::string& mode, SensorType sensor, const SlamSettings& settings) {
  // A single camera maps by default when its config is a single-camera one
  // (mono, mono_inertial); the first camera of a stereo config localises in
  // that rig's maps by default.
  const bool single_camera = is_single_camera(sensor);
  const bool single_camera_config = is_single_camera(settings.sensor);
  if (mode.empty()) return single_camera && !single_camera_config ? SessionMode::kLocalize : SessionMode::kMap;
  if (mode == "localize") return SessionMode::kLocalize;
  if (mode != "map") throw_bad_request("unknown mode '" + mode + "' (map or localize)");
  return SessionMode::kMap;
}

SlamSettings monocular_settings(SlamSettings settings, SensorType sensor) {
  if (sensor == SensorType::kMonocularInertial && !settings.imu)
    throw_bad_request("a mono_inertial session needs a config with its IMU (IMU.* keys); this one has none");
  settings.sensor = sensor;
  if (sensor != SensorType::kMonocularInertial) settings.imu.reset();
  return settings;
}

Pose3 single_camera_T_b_c(const SlamSettings& settings) {
  if (!settings.camera1) return settings.camera0.T_b_c;
  return StereoRectifier(settings.camera0, *settings.camera1).rectified_left().T_b_c;
}

void check_max_lag(const std::optional<double>& max_lag_s) {
  if (max_lag_s && !(std::isfinite(*max_lag_s) && *max_lag_s > 0.0 && *max_lag_s <= 60.0))
    throw_bad_request("max_lag_s must be a number of seconds in (0, 60], not " + std::to_string(*max_lag_s));
}

}  // namespace orbatlas
