#pragma once
// How the map service reads a session request (POST /v1/sessions, uploads):
// the name's limits, the sensor and mode it asks for with their defaults, and
// the settings a single camera maps with. Every refusal is a ServiceError
// (400), thrown before anything is created.
#include <cstddef>
#include <optional>
#include <string>

#include "core/geometry/pose.h"
#include "core/io/settings.h"
#include "core/server/service_results.h"

namespace orbatlas {

inline constexpr std::size_t kMaxSessionNameBytes = 200;  // UTF-8, no control characters

// At most kMaxSessionNameBytes of valid UTF-8 without control characters.
void check_session_name(const std::string& name);

// `sensor` as asked ("stereo", "mono", ...), else the settings' Sensor.type.
SensorType session_sensor(const std::string& sensor, const SlamSettings& settings);

// `mode` as asked ("map", "localize"), else map for a stereo rig, an RGB-D
// camera and a single camera of a single-camera config (mono, mono_inertial),
// localize for the first camera of a stereo config.
SessionMode session_mode(const std::string& mode, SensorType sensor, const SlamSettings& settings);

// The settings a single camera maps with: the config's first camera alone (of
// a stereo config: its left camera rectified as the rig's stereo maps are,
// StereoLeftFrontend), with its IMU for a mono_inertial session (400 when the
// config has none).
SlamSettings monocular_settings(SlamSettings settings, SensorType sensor);

// A real-time session's largest lag (POST /v1/sessions "max_lag_s"): none, or
// a finite number of seconds in (0, 60]; 400 otherwise.
void check_max_lag(const std::optional<double>& max_lag_s);

// Where a single camera that maps sits in the body: the rectified left camera
// of a stereo config, else the config's camera.
Pose3 single_camera_T_b_c(const SlamSettings& settings);

}  // namespace orbatlas
