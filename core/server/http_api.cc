#include "core/server/http_api.h"

#include <charconv>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>

#include "core/common/log.h"
#include "core/io/tum_trajectory.h"
#include "core/server/api_error.h"
#include "core/server/atlas_service.h"
#include "core/server/image_decode.h"
#include "core/server/pose_json.h"
#include "core/server/upload_jobs.h"

// Last: <httplib.h> pulls in <resolv.h>, whose macro _res breaks Eigen's headers.
#include <httplib.h>

namespace orbatlas {
namespace {

using httplib::Request;
using httplib::Response;
using json = nlohmann::json;

void reply_json(Response& res, const json& body, int status = 200) {
  res.status = status;
  res.set_content(body.dump(), "application/json");
}

void reply_error(Response& res, int status, const std::string& code, const std::string& message) {
  reply_json(res, {{"error", {{"code", code}, {"message", message}}}}, status);
}

// Every handler runs inside this: service errors become JSON replies.
void run_guarded(const Request& req, Response& res, const std::function<void()>& handler) {
  try {
    handler();
  } catch (const ApiError& e) {
    reply_error(res, e.status(), e.code(), e.what());
  } catch (const DataError& e) {
    reply_error(res, 422, "bad_input", e.what());
  } catch (const json::exception& e) {
    reply_error(res, 400, "bad_json", std::string("malformed request: ") + e.what());
  } catch (const std::exception& e) {
    log_warn(req.method + " " + req.path + ": " + e.what());
    reply_error(res, 500, "internal", e.what());
  }
}

template <class Handler>
auto guarded(Handler handler) {
  return [handler](const Request& req, Response& res) { run_guarded(req, res, [&] { handler(req, res); }); };
}

std::uint64_t id_from(const Request& req, std::size_t group, const char* what) {
  const std::string& text = req.matches[group];
  std::uint64_t id = 0;
  const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), id);
  if (ec != std::errc() || ptr != text.data() + text.size()) throw_not_found(std::string("no ") + what + " " + text);
  return id;
}

json parse_json_body(const Request& req) {
  if (req.body.empty()) throw_bad_request("the request needs a JSON body");
  json body = json::parse(req.body);  // json::exception: 400
  if (!body.is_object()) throw_bad_request("the JSON body must be an object");
  return body;
}

std::string optional_string(const json& body, const char* key) {
  if (!body.contains(key)) return {};
  if (!body[key].is_string()) throw_bad_request(std::string("'") + key + "' must be a string");
  return body[key].get<std::string>();
}

// A multipart field as text ("" when absent).
std::string form_text(const Request& req, const char* key) {
  return req.has_file(key) ? req.get_file_value(key).content : std::string();
}

std::int64_t form_integer(const Request& req, const char* key, bool required) {
  const std::string text = form_text(req, key);
  if (text.empty()) {
    if (required) throw_bad_request(std::string("the form field '") + key + "' is missing");
    return 0;
  }
  std::int64_t v = 0;
  const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || ptr != text.data() + text.size())
    throw_bad_request(std::string("the form field '") + key + "' must be an integer, got '" + text.substr(0, 40) + "'");
  return v;
}

std::optional<RawImageSize> raw_size(const Request& req) {
  if (!req.has_file("width") && !req.has_file("height")) return std::nullopt;
  return RawImageSize{static_cast<int>(form_integer(req, "width", true)),
                      static_cast<int>(form_integer(req, "height", true))};
}

void require_multipart(const Request& req, const char* fields) {
  if (!req.is_multipart_form_data())
    throw_bad_request(std::string("this route takes multipart/form-data with the fields ") + fields);
}

json session_list(const AtlasService& service) {
  json list = json::array();
  for (const auto& s : service.sessions()) list.push_back(service.session_status(s->id()));
  return {{"sessions", list}};
}

bool authorised(const Request& req, const std::string& token) {
  const std::string expected = "Bearer " + token;
  const std::string given = req.get_header_value("Authorization");
  if (given.size() != expected.size()) return false;
  unsigned char diff = 0;  // the same time whatever the first wrong character
  for (std::size_t i = 0; i < given.size(); ++i) diff |= static_cast<unsigned char>(given[i] ^ expected[i]);
  return diff == 0;
}

void install_session_routes(httplib::Server& server, AtlasService& service) {
  server.Post("/v1/sessions", guarded([&service](const Request& req, Response& res) {
    const json body = parse_json_body(req);
    SessionRequest request;
    request.name = optional_string(body, "name");
    if (body.contains("sensor")) request.sensor = optional_string(body, "sensor");
    request.settings.config = optional_string(body, "config");
    request.settings.settings_yaml = optional_string(body, "settings_yaml");
    const SessionId id = service.create_session(request);
    reply_json(res, {{"id", id}, {"session", service.session_status(id)}}, 201);
  }));
  server.Get("/v1/sessions", guarded([&service](const Request&, Response& res) { reply_json(res, session_list(service)); }));
  server.Get(R"(/v1/sessions/(\d+))", guarded([&service](const Request& req, Response& res) {
    reply_json(res, service.session_status(id_from(req, 1, "session")));
  }));
  server.Post(R"(/v1/sessions/(\d+)/frames)", guarded([&service](const Request& req, Response& res) {
    const auto start = std::chrono::steady_clock::now();
    const SessionId id = id_from(req, 1, "session");
    service.session(id);  // 404 before looking at the body
    require_multipart(req, "'t_ns', 'left', 'right' (and 'width', 'height' for raw pixels)");
    const TimestampNs t_ns = form_integer(req, "t_ns", true);
    if (!req.has_file("left"))
      throw_bad_request("a frame needs the image 'left' (and 'right' for a stereo session)");
    const auto raw = raw_size(req);
    const cv::Mat left = decode_request_image(req.get_file_value("left").content, raw, "left image");
    // A single-camera session takes 'left' alone; the session says which it needs.
    const cv::Mat right = req.has_file("right")
                              ? decode_request_image(req.get_file_value("right").content, raw, "right image")
                              : cv::Mat();
    const FrameReply r = service.process_frame(id, t_ns, left, right);
    json body = {{"t_ns", r.result.t_ns},
                 {"state", tracking_state_name(r.result.state)},
                 {"tracked", r.result.tracked},
                 {"keyframe", r.result.keyframe},
                 {"inliers", r.result.inliers},
                 {"tracking_ms", r.tracking_ms}};
    if (r.result.tracked) {
      body["map"] = r.result.map;
      body["T_w_b"] = pose_to_json(r.result.T_w_b);
    }
    body["server_ms"] = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    reply_json(res, body);
  }));
  server.Post(R"(/v1/sessions/(\d+)/imu)", guarded([&service](const Request& req, Response& res) {
    const SessionId id = id_from(req, 1, "session");
    service.session(id);
    const json body = parse_json_body(req);
    if (!body.contains("samples") || !body["samples"].is_array())
      throw_bad_request("'samples' must be an array of [t_ns, gx, gy, gz, ax, ay, az]");
    std::vector<ImuSample> samples;
    for (const json& row : body["samples"]) {
      if (!row.is_array() || row.size() != 7 || !row[0].is_number_integer())
        throw_bad_request("each IMU sample is [t_ns (integer), gx, gy, gz (rad/s), ax, ay, az (m/s^2)]");
      ImuSample s;
      s.t_ns = row[0].get<TimestampNs>();
      for (int k = 0; k < 3; ++k) {
        s.gyro[k] = row[1 + k].get<double>();
        s.accel[k] = row[4 + k].get<double>();
      }
      samples.push_back(s);
    }
    reply_json(res, {{"accepted", service.add_imu(id, samples)}});
  }));
  server.Post(R"(/v1/sessions/(\d+)/finish)", guarded([&service](const Request& req, Response& res) {
    reply_json(res, service.finish_session(id_from(req, 1, "session")));
  }));
  server.Get(R"(/v1/sessions/(\d+)/trajectory)", guarded([&service](const Request& req, Response& res) {
    const auto [trajectory, maps] = service.trajectory(id_from(req, 1, "session"));
    res.set_content(format_tum_trajectory(trajectory, maps), "text/plain");
  }));
}

void install_map_routes(httplib::Server& server, AtlasService& service) {
  server.Get("/v1/maps", guarded([&service](const Request&, Response& res) {
    reply_json(res, {{"maps", service.maps_json()}});
  }));
  server.Get(R"(/v1/maps/(\d+))", guarded([&service](const Request& req, Response& res) {
    reply_json(res, service.map_json(id_from(req, 1, "map")));
  }));
  server.Get("/v1/merges", guarded([&service](const Request&, Response& res) { reply_json(res, service.merges_json()); }));
  server.Get(R"(/v1/maps/(\d+)/points\.ply)", guarded([&service](const Request& req, Response& res) {
    res.set_content(service.map_points_ply(id_from(req, 1, "map")), "application/ply");
  }));
  server.Post("/v1/localize", guarded([&service](const Request& req, Response& res) {
    require_multipart(req, "'image' (or 'left' and 'right'), 'config' or 'settings_yaml', optional 'map'");
    LocalizeRequest request;
    request.settings.config = form_text(req, "config");
    request.settings.settings_yaml = form_text(req, "settings_yaml");
    if (req.has_file("map")) request.map = static_cast<MapId>(form_integer(req, "map", true));
    const auto raw = raw_size(req);
    const char* left_key = req.has_file("image") ? "image" : "left";
    if (!req.has_file(left_key)) throw_bad_request("localisation needs an 'image' (or a 'left' and 'right' pair)");
    request.left = decode_request_image(req.get_file_value(left_key).content, raw, "image");
    if (req.has_file("right")) request.right = decode_request_image(req.get_file_value("right").content, raw, "right image");
    const LocalizeReply r = service.localize(request);
    json body = {{"recognised", r.recognised}, {"candidates", r.candidates}, {"ms", r.ms}};
    if (r.recognised) {
      body["map"] = r.map;
      body["T_w_b"] = pose_to_json(r.T_w_b);
      body["inliers"] = r.inliers;
    } else {
      body["reason"] = r.candidates == 0 ? "no keyframe of the atlas looks like this image"
                                         : "no candidate place gave a consistent pose";
    }
    reply_json(res, body);
  }));
}

void install_upload_routes(httplib::Server& server, AtlasService& service, UploadJobs* jobs, std::uint64_t max_bytes) {
  server.Post("/v1/uploads", [&service, jobs, max_bytes](const Request& req, Response& res,
                                                         const httplib::ContentReader& reader) {
    // A refusal comes before the body is read; what is left of it must not be
    // taken for the next request on this connection: the client closes it.
    res.set_header("Connection", "close");
    run_guarded(req, res, [&] {
      if (!jobs) throw ApiError(503, "unavailable", "this server takes no uploads");
      SessionRequest request;
      request.name = req.get_param_value("name");
      request.settings.config = req.has_param("config") ? req.get_param_value("config") : "euroc/stereo";
      if (req.has_param("sensor")) request.sensor = req.get_param_value("sensor");
      service.check_upload(request);  // before receiving gigabytes for nothing
      const std::filesystem::path path = jobs->new_upload_path();
      struct Discard {  // the archive, unless a job took it
        std::filesystem::path path;
        bool keep = false;
        ~Discard() {
          std::error_code ec;
          if (!keep) std::filesystem::remove(path, ec);
        }
      } discard{path};
      std::ofstream out(path, std::ios::binary);
      if (!out) throw Error("cannot store an upload in " + path.parent_path().string());
      std::uint64_t bytes = 0;
      bool too_large = false;
      const bool complete = reader([&](const char* data, std::size_t n) {
        bytes += n;
        if (bytes > max_bytes) {
          too_large = true;
          return false;
        }
        out.write(data, static_cast<std::streamsize>(n));
        return static_cast<bool>(out);
      });
      out.close();
      if (too_large) throw ApiError(413, "too_large", "uploads are limited to " + std::to_string(max_bytes) + " bytes");
      if (!out) throw Error("cannot store the upload (disk full?)");
      if (!complete) throw_bad_request("the upload was cut short after " + std::to_string(bytes) + " bytes");
      if (bytes == 0) throw_bad_request("the upload is empty: send a tar of an EuRoC ASL folder");
      const JobId id = jobs->submit(path, request);
      discard.keep = true;
      reply_json(res, {{"job", id}, {"status", jobs->job_json(id)}}, 202);
    });
  });
  server.Get("/v1/jobs", guarded([jobs](const Request&, Response& res) {
    reply_json(res, {{"jobs", jobs ? jobs->jobs_json() : json::array()}});
  }));
  server.Get(R"(/v1/jobs/(\d+))", guarded([jobs](const Request& req, Response& res) {
    const JobId id = id_from(req, 1, "job");
    if (!jobs) throw_not_found("no job " + std::to_string(id));
    reply_json(res, jobs->job_json(id));
  }));
}

}  // namespace

void install_http_api(httplib::Server& server, AtlasService& service, const HttpApiOptions& options,
                      UploadJobs* jobs) {
  const HttpApiOptions opts = options;
  server.set_pre_routing_handler([opts](const Request& req, Response& res) {
    if (!opts.token.empty() && req.path != "/healthz" && !authorised(req, opts.token)) {
      res.set_header("WWW-Authenticate", "Bearer");
      res.set_header("Connection", "close");  // the body was not read: the connection cannot carry another request
      reply_error(res, 401, "unauthorized",
                  req.has_header("Authorization") ? "wrong token" : "this server needs 'Authorization: Bearer <token>'");
      return httplib::Server::HandlerResponse::Handled;
    }
    if (req.path.rfind("/v1/uploads", 0) != 0) {
      if (req.get_header_value("Transfer-Encoding").find("chunked") != std::string::npos) {
        reply_error(res, 411, "length_required", "send this request with a Content-Length (chunked bodies are for uploads)");
        res.set_header("Connection", "close");
        return httplib::Server::HandlerResponse::Handled;
      }
      const std::string length = req.get_header_value("Content-Length");
      std::uint64_t bytes = 0;
      std::from_chars(length.data(), length.data() + length.size(), bytes);
      if (bytes > opts.max_body_bytes) {
        reply_error(res, 413, "too_large",
                    "the body has " + length + " bytes; this route takes at most " + std::to_string(opts.max_body_bytes));
        res.set_header("Connection", "close");
        return httplib::Server::HandlerResponse::Handled;
      }
    }
    return httplib::Server::HandlerResponse::Unhandled;
  });
  // Errors httplib produces itself (no route, a body over its limit...) get a JSON body too.
  server.set_error_handler(httplib::Server::HandlerWithResponse([](const Request& req, Response& res) {
    if (!res.body.empty()) return httplib::Server::HandlerResponse::Unhandled;
    const std::string message = res.status == 404 ? "no route " + req.method + " " + req.path
                                                  : "HTTP status " + std::to_string(res.status);
    reply_error(res, res.status, res.status == 404 ? "not_found" : "http_error", message);
    return httplib::Server::HandlerResponse::Handled;
  }));
  if (options.log_requests) {
    server.set_logger([](const Request& req, const Response& res) {
      log_info(req.method + " " + req.path + " -> " + std::to_string(res.status));
    });
  }
  server.Get("/healthz", guarded([&service](const Request&, Response& res) { reply_json(res, service.health()); }));
  server.Get("/metrics", guarded([&service, jobs](const Request&, Response& res) {
    std::string text = service.metrics_text();
    text += "# HELP orbatlas_jobs Upload jobs by state.\n# TYPE orbatlas_jobs gauge\n";
    for (const char* state : {"queued", "extracting", "running", "done", "failed", "cancelled"})
      text += std::string("orbatlas_jobs{state=\"") + state + "\"} " + std::to_string(jobs ? jobs->count(state) : 0) + "\n";
    res.set_content(text, "text/plain; version=0.0.4");
  }));
  install_session_routes(server, service);
  install_map_routes(server, service);
  install_upload_routes(server, service, jobs, options.max_upload_bytes);
}

}  // namespace orbatlas
