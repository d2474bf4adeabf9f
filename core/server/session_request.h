#pragma once
// What a client asks for when it starts a session (POST /v1/sessions) or
// localises an image: its settings, sensor, mode and real-time bound; when a
// frame's request began (its latency is counted from there).
#include <chrono>
#include <optional>
#include <string>

namespace orbatlas {

// Settings of a new session or of a localisation request: a config name
// ("euroc/stereo") or the text of an ORB-SLAM3-style YAML file.
struct SettingsSource {
  std::string config;
  std::string settings_yaml;
};

struct SessionRequest {
  std::string name;
  std::string sensor;  // empty: the config's Sensor.type
  // "map" or "localize"; empty: as session_mode (session_rules.h) decides.
  std::string mode;
  SettingsSource settings;
  // A real-time client: a frame that arrives more than this many seconds
  // behind the session's sensor clock is skipped (FrameReply::skipped), so the
  // session catches up instead of falling further behind. None: every frame is
  // tracked however late.
  std::optional<double> max_lag_s;
};

// When a frame's request began to be handled and how long its images took to
// decode (the HTTP layer's part), so that its latency is counted whole.
struct FrameRequestTiming {
  std::optional<std::chrono::steady_clock::time_point> started;  // none: when process_frame is called
  double decode_ms = 0.0;
};

}  // namespace orbatlas
