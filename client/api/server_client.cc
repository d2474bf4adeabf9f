#include "client/api/server_client.h"

#include <filesystem>

#include <functional>
#include <opencv2/imgcodecs.hpp>

#include "core/archive/tar_writer.h"
#include "core/common/error.h"
#include "core/common/text_file.h"
#include "core/io/kitti_odometry.h"

// Last: <httplib.h> pulls in <resolv.h>, whose macro _res breaks Eigen's headers.
#include <httplib.h>

namespace orbatlas {
namespace {

using json = nlohmann::json;

std::string image_bytes(const cv::Mat& image, ImageEncoding encoding) {
  ORBATLAS_CHECK(
      !image.empty() && (image.type() == CV_8UC1 || (image.type() == CV_16UC1 && encoding == ImageEncoding::kPng)),
      "the client sends 8-bit grey images (and 16-bit depth images as PNG)");
  if (encoding == ImageEncoding::kPng) {
    std::vector<unsigned char> png;
    ORBATLAS_CHECK(cv::imencode(".png", image, png, {cv::IMWRITE_PNG_COMPRESSION, 1}), "cannot encode a PNG");
    return std::string(png.begin(), png.end());
  }
  const cv::Mat dense = image.isContinuous() ? image : image.clone();
  return std::string(reinterpret_cast<const char*>(dense.data), dense.total());
}

// An 8-bit grey image's pixels, row by row, at the end of `body` (no copy of the image first).
void append_raw_pixels(std::string& body, const cv::Mat& image) {
  ORBATLAS_CHECK(image.type() == CV_8UC1, "raw frames are 8-bit grey images");
  for (int y = 0; y < image.rows; ++y) body.append(image.ptr<char>(y), static_cast<std::size_t>(image.cols));
}

void add_image(httplib::MultipartFormDataItems& items, const char* name, const cv::Mat& image, ImageEncoding encoding) {
  items.push_back({name, image_bytes(image, encoding),
                   std::string(name) + (encoding == ImageEncoding::kPng ? ".png" : ".raw"),
                   encoding == ImageEncoding::kPng ? "image/png" : "application/octet-stream"});
}

void add_raw_size(httplib::MultipartFormDataItems& items, const cv::Mat& image, ImageEncoding encoding) {
  if (encoding != ImageEncoding::kRaw) return;
  items.push_back({"width", std::to_string(image.cols), "", ""});
  items.push_back({"height", std::to_string(image.rows), "", ""});
}

std::string url_encode(const std::string& text) {
  std::string out;
  for (const unsigned char c : text) {
    if (std::isalnum(c) || c == '-' || c == '_' || c == '.' || c == '~' || c == '/') {
      out += static_cast<char>(c);
    } else {
      char buf[4];
      std::snprintf(buf, sizeof buf, "%%%02X", c);
      out += buf;
    }
  }
  return out;
}

}  // namespace

void throw_server_error(int status, const std::string& body) {
  std::string code = "http_error", message = body.substr(0, 300);
  try {
    const json j = json::parse(body);
    code = j.at("error").at("code").get<std::string>();
    message = j.at("error").at("message").get<std::string>();
  } catch (const std::exception&) {
  }
  throw ServerError(status, code, message);
}

ServerClient::ServerClient(const std::string& url, std::string token, const std::string& ca)
    : url_(url), token_(std::move(token)), client_(std::make_unique<httplib::Client>(url)) {
  ORBATLAS_CHECK(client_->is_valid(), "not a server URL: '" << url << "' (e.g. http://127.0.0.1:8080)");
  if (url.rfind("https://", 0) == 0) {
    client_->enable_server_certificate_verification(true);
    if (!ca.empty()) {
      ORBATLAS_CHECK(std::filesystem::is_regular_file(ca), "--ca " << ca << ": no such file");
      client_->set_ca_cert_path(ca.c_str());
    }
  } else {
    ORBATLAS_CHECK(ca.empty(), "--ca is for https:// servers, not '" << url << "'");
  }
  client_->set_keep_alive(true);
  client_->set_tcp_nodelay(true);  // no 40 ms delayed-ACK stalls between a request's packets
  client_->set_connection_timeout(5);
  client_->set_read_timeout(300);  // finishing a long session waits for mapping and a durable checkpoint
  client_->set_write_timeout(60);
  if (!token_.empty()) client_->set_bearer_token_auth(token_);
}

ServerClient::~ServerClient() = default;

httplib::Client& ServerClient::http() { return *client_; }

namespace {

// A keep-alive connection the server closed while it sat idle (its slow-client
// guard makes room for other clients) fails the next request on it. A request
// that could not be written was never received: it is sent once more, on a new
// connection; a GET, a localisation and a frame also when the reply could not
// be read (the first two change nothing; a frame the server did take is refused
// the second time, 422 for a timestamp not after the last, and the session goes on).
httplib::Result send(const std::function<httplib::Result()>& request, bool idempotent) {
  httplib::Result result = request();
  if (!result && (result.error() == httplib::Error::Write || (idempotent && result.error() == httplib::Error::Read)))
    result = request();
  return result;
}

const httplib::Response& checked(const httplib::Result& result, const std::string& url, const std::string& what) {
  if (!result)
    throw Error("cannot reach the server at " + url + " (" + what + "): " + httplib::to_string(result.error()));
  if (result->status >= 400) throw_server_error(result->status, result->body);
  return *result;
}

}  // namespace

json ServerClient::get_json(const std::string& path) {
  return json::parse(checked(send([&] { return client_->Get(path); }, true), url_, path).body);
}

std::string ServerClient::get_text(const std::string& path) {
  return checked(send([&] { return client_->Get(path); }, true), url_, path).body;
}

json ServerClient::post_json(const std::string& path, const json& body) {
  const std::string text = body.dump();
  return json::parse(
      checked(send([&] { return client_->Post(path, text, "application/json"); }, false), url_, path).body);
}

SettingsChoice choose_settings(const std::string& config) {
  std::error_code ec;
  if (std::filesystem::is_regular_file(config, ec)) return {"", read_text_file(config)};
  const std::string ext = std::filesystem::path(config).extension().string();
  ORBATLAS_CHECK(ext != ".yaml" && ext != ".yml",
                 "no settings file " << config
                                     << " (give an existing file, or a config name the server knows such as "
                                        "euroc/stereo)");
  return {config, ""};
}

json ServerClient::start_session(const std::string& config, const std::string& name, const std::string& sensor,
                                 const std::string& mode, std::optional<double> max_lag_s,
                                 const std::string& settings_yaml) {
  const SettingsChoice settings = settings_yaml.empty() ? choose_settings(config) : SettingsChoice{"", settings_yaml};
  json body = json::object();
  if (!settings.config.empty()) body["config"] = settings.config;
  if (!settings.settings_yaml.empty()) body["settings_yaml"] = settings.settings_yaml;
  if (!name.empty()) body["name"] = name;
  if (!sensor.empty()) body["sensor"] = sensor;
  if (!mode.empty()) body["mode"] = mode;
  if (max_lag_s) body["max_lag_s"] = *max_lag_s;
  return post_json("/v1/sessions", body);
}

json ServerClient::post_frame(std::uint64_t session, std::int64_t t_ns, const cv::Mat& left, const cv::Mat& right,
                              ImageEncoding encoding) {
  const std::string path = "/v1/sessions/" + std::to_string(session) + "/frames";
  if (encoding == ImageEncoding::kRaw && right.depth() != CV_16U) {
    // One body of pixels, left then right (docs/api.md "Frames"): no multipart on either side.
    ORBATLAS_CHECK(right.empty() || right.size() == left.size(), "the left and right images differ in size");
    std::string body;
    body.reserve(left.total() + right.total());
    for (const cv::Mat* image : {&left, &right})
      if (!image->empty()) append_raw_pixels(body, *image);
    const std::string target = path + "?t_ns=" + std::to_string(t_ns) + "&width=" + std::to_string(left.cols) +
                               "&height=" + std::to_string(left.rows);
    return json::parse(
        checked(send([&] { return client_->Post(target, body, "application/octet-stream"); }, true), url_, path).body);
  }
  httplib::MultipartFormDataItems items;
  items.push_back({"t_ns", std::to_string(t_ns), "", ""});
  add_image(items, "left", left, encoding);
  if (right.depth() == CV_16U) {
    add_image(items, "depth", right, ImageEncoding::kPng);  // an RGB-D frame's depth: always a 16-bit PNG
  } else if (!right.empty()) {
    add_image(items, "right", right, encoding);
  }
  add_raw_size(items, left, encoding);
  return json::parse(checked(send([&] { return client_->Post(path, items); }, true), url_, path).body);
}

json ServerClient::post_imu(std::uint64_t session, const std::vector<ImuSample>& samples) {
  json rows = json::array();
  for (const ImuSample& s : samples)
    rows.push_back({s.t_ns, s.gyro.x(), s.gyro.y(), s.gyro.z(), s.accel.x(), s.accel.y(), s.accel.z()});
  return post_json("/v1/sessions/" + std::to_string(session) + "/imu", json{{"samples", std::move(rows)}});
}

json ServerClient::finish_session(std::uint64_t session) {
  return post_json("/v1/sessions/" + std::to_string(session) + "/finish", json::object());
}

std::string ServerClient::trajectory_tum(std::uint64_t session) {
  return get_text("/v1/sessions/" + std::to_string(session) + "/trajectory");
}

json ServerClient::localize(const std::string& config, const cv::Mat& left, const cv::Mat& right,
                            std::optional<std::uint64_t> map, ImageEncoding encoding,
                            const std::string& settings_yaml) {
  const SettingsChoice settings = settings_yaml.empty() ? choose_settings(config) : SettingsChoice{"", settings_yaml};
  httplib::MultipartFormDataItems items;
  if (!settings.config.empty()) items.push_back({"config", settings.config, "", ""});
  if (!settings.settings_yaml.empty()) items.push_back({"settings_yaml", settings.settings_yaml, "", ""});
  if (map) items.push_back({"map", std::to_string(*map), "", ""});
  add_image(items, right.empty() ? "image" : "left", left, encoding);
  if (!right.empty()) add_image(items, "right", right, encoding);
  add_raw_size(items, left, encoding);
  return json::parse(
      checked(send([&] { return client_->Post("/v1/localize", items); }, true), url_, "/v1/localize").body);
}

std::uint64_t ServerClient::upload(const std::filesystem::path& dataset, const std::string& config,
                                   const std::string& name,
                                   const std::function<void(std::uint64_t, std::uint64_t)>& progress) {
  ORBATLAS_CHECK(std::filesystem::is_directory(dataset / "mav0") ||
                     std::filesystem::is_regular_file(dataset / "rgb.txt") || is_kitti_sequence(dataset),
                 dataset << " holds no mav0/ folder (EuRoC ASL), rgb.txt (TUM RGB-D) nor image_0/, times.txt and "
                            "calib.txt (KITTI odometry)");
  ORBATLAS_CHECK(choose_settings(config).settings_yaml.empty(),
                 "an upload takes a config name the server knows (such as euroc/stereo), not the settings file "
                     << config << ": the body of an upload is the recording");
  const std::uint64_t total = directory_tar_size(dataset);
  // No config: the server takes the recording's own (a KITTI sequence's calib.txt), else euroc/stereo.
  std::string path = "/v1/uploads?";
  if (!config.empty()) path += "config=" + url_encode(config) + "&";
  if (!name.empty()) path += "name=" + url_encode(name);
  std::string failure;
  const auto result = client_->Post(
      path, static_cast<std::size_t>(total),
      [&](std::size_t offset, std::size_t, httplib::DataSink& sink) {
        if (offset != 0) return false;  // everything is written by the first call
        try {
          write_directory_tar(
              dataset,
              [&](const char* data, std::size_t n) {
                if (!sink.write(data, n)) throw Error("the connection closed while uploading");
              },
              progress);
        } catch (const std::exception& e) {
          failure = e.what();
          return false;
        }
        return true;
      },
      "application/x-tar");
  if (!failure.empty()) throw Error("upload of " + dataset.string() + " failed: " + failure);
  return json::parse(checked(result, url_, "/v1/uploads").body).at("job").get<std::uint64_t>();
}

}  // namespace orbatlas
