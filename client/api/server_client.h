#pragma once
// A client of the map server's HTTP API v1 (docs/api.md), used by the
// `orbatlas stream|upload|localize --server|sessions|maps|jobs` commands and the
// end-to-end tests. One connection, kept alive; not thread-safe (one client per
// thread). Errors: ServerError for a reply with an error status (its JSON code
// and message), Error when the server cannot be reached.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/core/mat.hpp>
#include <optional>
#include <string>

#include "core/common/error.h"
#include "core/io/euroc_types.h"

namespace httplib {
class Client;
}

namespace orbatlas {

class ServerError : public Error {
 public:
  ServerError(int status, std::string code, const std::string& message)
      : Error("server replied " + std::to_string(status) + " (" + code + "): " + message),
        status_(status),
        code_(std::move(code)) {}
  int status() const { return status_; }
  const std::string& code() const { return code_; }

 private:
  int status_;
  std::string code_;
};

enum class ImageEncoding { kRaw, kPng };  // raw: 8-bit pixels as they are (no decoding on the server)

// What `--config` means in every command: a settings file on this machine (an
// existing file, or a name ending in .yaml / .yml, which must then exist) is sent
// as its text (`settings_yaml`); anything else is a config name the server knows
// ("euroc/stereo"). Throws Error for a .yaml path that does not exist.
struct SettingsChoice {
  std::string config;         // a name the server knows, or empty
  std::string settings_yaml;  // the text of a local file, or empty
};
SettingsChoice choose_settings(const std::string& config);

class ServerClient {
 public:
  // url: "http://127.0.0.1:8080" or "https://..." (the server's certificate is
  // checked against `ca`, a PEM file, or the system's authorities when empty).
  explicit ServerClient(const std::string& url, std::string token = {}, const std::string& ca = {});
  ~ServerClient();
  ServerClient(const ServerClient&) = delete;
  ServerClient& operator=(const ServerClient&) = delete;

  nlohmann::json get_json(const std::string& path);
  std::string get_text(const std::string& path);
  nlohmann::json post_json(const std::string& path, const nlohmann::json& body);

  // POST /v1/sessions with a config name or a local settings file
  // (choose_settings), and a sensor (empty takes the config's Sensor.type);
  // returns the reply: {"id", "session": {... "sensor"}}.
  // `mode`: "map" or "localize" (empty: the server's default for the sensor).
  // `max_lag_s`: a real-time session, whose frames that arrive more than this
  // behind the sensor's clock the server skips.
  // `settings_yaml`, when given, is sent instead of `config`.
  nlohmann::json start_session(const std::string& config, const std::string& name = {}, const std::string& sensor = {},
                               const std::string& mode = {}, std::optional<double> max_lag_s = std::nullopt,
                               const std::string& settings_yaml = {});
  // The same; returns the session id.
  std::uint64_t create_session(const std::string& config, const std::string& name = {}) {
    return start_session(config, name).at("id").get<std::uint64_t>();
  }
  // POST /v1/sessions/{id}/frames (one image for a single-camera session:
  // `right` empty; an RGB-D session's `right` is its 16-bit depth image, sent
  // as the PNG 'depth'); the reply (pose, state, map, timings).
  nlohmann::json post_frame(std::uint64_t session, std::int64_t t_ns, const cv::Mat& left, const cv::Mat& right,
                            ImageEncoding encoding = ImageEncoding::kRaw);
  // POST /v1/sessions/{id}/imu: samples in time order (send those up to a
  // frame, and the first one past it, before the frame); the reply {"accepted"}.
  nlohmann::json post_imu(std::uint64_t session, const std::vector<ImuSample>& samples);
  nlohmann::json finish_session(std::uint64_t session);
  std::string trajectory_tum(std::uint64_t session);
  // POST /v1/localize: a single image when `right` is empty. The settings are
  // `settings_yaml` when given, else `config` as choose_settings reads it.
  nlohmann::json localize(const std::string& config, const cv::Mat& left, const cv::Mat& right = {},
                          std::optional<std::uint64_t> map = std::nullopt, ImageEncoding encoding = ImageEncoding::kPng,
                          const std::string& settings_yaml = {});

  // POST /v1/uploads: streams `dataset` (an EuRoC ASL, TUM RGB-D or KITTI
  // odometry folder) as a tar; returns the job id. `config` must be a name the
  // server knows (Error for a local settings file: an upload's body is the
  // archive); empty: the recording's own (a KITTI sequence's calib.txt), else euroc/stereo. `progress(bytes_sent,
  // bytes_total)` is called as it goes.
  std::uint64_t upload(const std::filesystem::path& dataset, const std::string& config, const std::string& name = {},
                       const std::function<void(std::uint64_t, std::uint64_t)>& progress = {});

  const std::string& url() const { return url_; }
  httplib::Client& http();  // for uploads and tests

 private:
  std::string url_;
  std::string token_;
  std::unique_ptr<httplib::Client> client_;
};

// The body of a reply with an error status as a ServerError (thrown).
[[noreturn]] void throw_server_error(int status, const std::string& body);

}  // namespace orbatlas
