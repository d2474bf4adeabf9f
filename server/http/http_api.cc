#include "server/http/http_api.h"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <filesystem>
#include <functional>
#include <memory>
#include <regex>
#include <sys/socket.h>
#include <nlohmann/json.hpp>
#include <prometheus/text_serializer.h>

#include "core/common/log.h"
#include "core/common/timestamp.h"
#include "core/io/settings.h"
#include "core/io/tum_trajectory.h"
#include "core/server/service_error.h"
#include "core/server/atlas_service.h"
#include "server/http/api_access.h"
#include "server/http/image_decode.h"
#include "server/http/imu_batch.h"
#include "core/common/parse_integer.h"
#include "server/http/raw_frame.h"
#include "core/persistence/map_rigs.h"
#include "wire/service_json.h"
#include "server/http/session_request_json.h"
#include "wire/pose_json.h"
#include "core/server/upload_jobs.h"

// Last: it includes <httplib.h>, which pulls in <resolv.h>, whose macro _res breaks Eigen's headers.
#include "server/http/http_router.h"

namespace orbatlas {

using namespace http_detail;  // NOLINT(google-build-using-namespace): the routes' shared helpers

namespace {

using HandlerResponse = httplib::Server::HandlerResponse;

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
  const auto v = parse_integer<std::int64_t>(text);
  if (!v)
    throw_bad_request(std::string("the form field '") + key + "' must be an integer, got '" + text.substr(0, 40) + "'");
  return *v;
}

std::optional<RawImageSize> raw_size(const Request& req) {
  if (!req.has_file("width") && !req.has_file("height")) return std::nullopt;
  const std::int64_t width = form_integer(req, "width", true), height = form_integer(req, "height", true);
  if (width <= 0 || height <= 0 || width > kMaxImageSide || height > kMaxImageSide)
    throw_bad_request("'width' and 'height' must be 1.." + std::to_string(kMaxImageSide) + ", got " +
                      std::to_string(width) + " and " + std::to_string(height));
  return RawImageSize{static_cast<int>(width), static_cast<int>(height)};
}

void require_multipart(const Request& req, const char* fields) {
  if (!req.is_multipart_form_data())
    throw_bad_request(std::string("this route takes multipart/form-data with the fields ") + fields);
}

// A session's status, with the client that started it (when the API has clients).
json session_json(const AtlasService& service, const ApiAccess& access, SessionId id) {
  json j = to_json(service.session_status(id));
  if (const auto owner = access.owner(id)) j["client"] = *owner;
  return j;
}

json session_list(const AtlasService& service, const ApiAccess& access) {
  json list = json::array();
  for (const auto& s : service.sessions()) list.push_back(session_json(service, access, s->id()));
  return {{"sessions", list}};
}

std::string lower_trimmed(std::string text) {
  const auto first = text.find_first_not_of(" \t"), last = text.find_last_not_of(" \t");
  text = first == std::string::npos ? std::string() : text.substr(first, last - first + 1);
  for (char& c : text) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return text;
}

void install_session_routes(Router& router, AtlasService& service, const std::shared_ptr<ApiAccess>& access) {
  router.post("/v1/sessions", ([&service, access](const Request& req, Response& res) {
                const SessionRequest request = parse_session_request(req.body);
                const SessionId id = service.create_session(request);
                if (const auto client = access->client_of(req)) access->set_owner(id, *client);
                reply_json(res, {{"id", id}, {"session", session_json(service, *access, id)}}, 201);
              }));
  router.get("/v1/sessions",
             ([&service, access](const Request&, Response& res) { reply_json(res, session_list(service, *access)); }));
  router.get(R"(/v1/sessions/(\d+))", ([&service, access](const Request& req, Response& res) {
               reply_json(res, session_json(service, *access, id_from(req, 1, "session")));
             }));
  router.post(
      R"(/v1/sessions/(\d+)/frames)", ([&service, access](const Request& req, Response& res) {
        const auto start = std::chrono::steady_clock::now();
        const SessionId id = id_from(req, 1, "session");
        const auto session = service.session(id);  // 404 before looking at the body
        access->require_owner(req, id, false);
        const CameraCalibration& camera = session->info().cameras.at(0);
        const cv::Size expected(camera.width, camera.height);
        const bool rgbd = session->info().sensor == SensorType::kRgbd;
        TimestampNs t_ns = 0;
        cv::Mat left, right;
        if (is_raw_frame_request(req)) {
          // One body of raw pixels (server/http/raw_frame.h): no multipart parsing, no decoding.
          if (rgbd)
            throw_bad_request("an RGB-D session's frame is multipart/form-data: 'left' and its 'depth' (a 16-bit PNG)");
          RawFrame raw = parse_raw_frame(req, expected, !is_single_camera(session->info().sensor));
          t_ns = raw.t_ns;
          left = std::move(raw.left);
          right = std::move(raw.right);
        } else {
          require_multipart(req,
                            "'t_ns', 'left', 'right' or 'depth' (and 'width', 'height' for raw pixels); or an "
                            "application/octet-stream body of raw pixels");
          t_ns = form_integer(req, "t_ns", true);
          if (!req.has_file("left"))
            throw_bad_request(
                "a frame needs the image 'left' (and 'right' for a stereo session, 'depth' for an RGB-D one)");
          if (rgbd && (req.has_file("right") || !req.has_file("depth")))
            throw_bad_request("an RGB-D session's frame is 'left' and its 'depth' (a 16-bit PNG), not a pair");
          if (!rgbd && req.has_file("depth"))
            throw_bad_request("a 'depth' image belongs to an RGB-D session; this one is " +
                              std::string(sensor_type_name(session->info().sensor)));
          const auto raw = raw_size(req);
          left = decode_request_image(req.get_file_value("left").content, raw, "left image", expected);
          // A single-camera session takes 'left' alone; the session says which it needs.
          right = rgbd ? decode_request_depth(req.get_file_value("depth").content, "depth image", expected)
                  : req.has_file("right")
                      ? decode_request_image(req.get_file_value("right").content, raw, "right image", expected)
                      : cv::Mat();
        }
        const double decode_ms =
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
        const FrameReply r = service.process_frame(id, t_ns, left, right, FrameRequestTiming{start, decode_ms});
        json body = {{"t_ns", r.result.t_ns},
                     {"state", tracking_state_name(r.result.state)},
                     {"tracked", r.result.tracked},
                     {"by_imu", r.result.by_imu},
                     {"keyframe", r.result.keyframe},
                     {"inliers", r.result.inliers},
                     {"tracking_ms", r.tracking_ms},
                     {"skipped", r.skipped},
                     {"maps_busy", r.result.maps_busy},
                     {"local_keyframes", r.result.local_keyframes},
                     {"local_points", r.result.local_points},
                     {"maps_wait_ms", r.result.maps_wait_ms},
                     {"maps_edits", r.result.maps_edits}};
        if (r.result.tracked) {
          body["map"] = r.result.map;
          body["T_w_b"] = pose_to_json(r.result.T_w_b);
        }
        if (r.jump_m) body["jump_m"] = *r.jump_m;
        body["server_ms"] = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
        reply_json(res, body);
      }));
  router.post(R"(/v1/sessions/(\d+)/imu)", ([&service, access](const Request& req, Response& res) {
                const SessionId id = id_from(req, 1, "session");
                service.session(id);
                access->require_owner(req, id, false);
                const std::vector<ImuSample> samples = parse_imu_batch(req.body);
                reply_json(res, {{"accepted", service.add_imu(id, samples)}});
              }));
  router.post(R"(/v1/sessions/(\d+)/finish)", ([&service, access](const Request& req, Response& res) {
                const SessionId id = id_from(req, 1, "session");
                service.session(id);  // 404 first
                access->require_owner(req, id, true);
                service.finish_session(id);
                reply_json(res, session_json(service, *access, id));
              }));
  router.get(R"(/v1/sessions/(\d+)/trajectory)", ([&service](const Request& req, Response& res) {
               const SessionTrajectory t = service.trajectory(id_from(req, 1, "session"));
               // Frames that no longer resolve are said, never silently dropped.
               res.set_header("X-Orbatlas-Frames", std::to_string(t.frames));
               res.set_header("X-Orbatlas-Unresolved-Frames", std::to_string(t.unresolved));
               std::string text =
                   "# " + std::to_string(t.frames) + " frames tracked, " + std::to_string(t.poses.size()) + " below" +
                   (t.unresolved ? ", " + std::to_string(t.unresolved) + " not resolvable (their keyframe is in no map)"
                                 : std::string()) +
                   "\n";
               res.set_content(text + format_tum_trajectory(t.poses, t.maps), "text/plain");
             }));
}

void install_map_routes(Router& router, AtlasService& service) {
  router.get("/v1/maps", ([&service](const Request&, Response& res) {
               json maps = json::array();
               for (const MapSummary& map : service.maps()) maps.push_back(to_json(map));
               reply_json(res, {{"maps", maps}});
             }));
  router.get(R"(/v1/maps/(\d+))", ([&service](const Request& req, Response& res) {
               reply_json(res, to_json(service.map(id_from(req, 1, "map"))));
             }));
  router.get("/v1/merges", ([&service](const Request&, Response& res) { reply_json(res, to_json(service.merges())); }));
  router.get("/v1/replicas", ([&service](const Request&, Response& res) {
               reply_json(res, replicas_json(service.replicas(), service.replica()));
             }));
  router.get(R"(/v1/maps/(\d+)/points\.ply)", ([&service](const Request& req, Response& res) {
               res.set_content(to_ply(service.map_points(id_from(req, 1, "map"))), "application/ply");
             }));
  router.post("/v1/localize", ([&service](const Request& req, Response& res) {
                require_multipart(req, "'image' (or 'left' and 'right'), 'config' or 'settings_yaml', optional 'map'");
                LocalizeRequest request;
                request.settings.config = form_text(req, "config");
                request.settings.settings_yaml = form_text(req, "settings_yaml");
                if (req.has_file("map")) {
                  const std::int64_t map = form_integer(req, "map", true);
                  if (map < 0)
                    throw_bad_request("the form field 'map' must be a map id (0 or more), got " + std::to_string(map));
                  request.map = static_cast<MapId>(map);
                }
                const auto raw = raw_size(req);
                const char* left_key = req.has_file("image") ? "image" : "left";
                if (!req.has_file(left_key))
                  throw_bad_request("localisation needs an 'image' (or a 'left' and 'right' pair)");
                const cv::Size expected = service.localize_image_size(request.settings);
                request.left = decode_request_image(req.get_file_value(left_key).content, raw, "image", expected);
                if (req.has_file("right"))
                  request.right =
                      decode_request_image(req.get_file_value("right").content, raw, "right image", expected);
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

}  // namespace

std::vector<std::pair<std::string, std::string>> server_path_redactions(const AtlasService& service) {
  const std::filesystem::path db = std::filesystem::absolute(service.db_path()).lexically_normal();
  // Longest first: the work folder and the file before the folder holding them.
  return {{db.string() + ".work", "<work>"},
          {db.string(), "<atlas>"},
          {service.config_dir().string(), "<configs>"},
          {db.parent_path().string(), "<data>"},
          {service.db_path().string() + ".work", "<work>"},
          {service.db_path().string(), "<atlas>"}};
}

namespace {

HandlerResponse refuse(Response& res, int status, const std::string& code, const std::string& message) {
  reply_error(res, status, code, message);
  res.set_header("Connection", "close");  // the body was not read: the connection cannot carry another request
  return HandlerResponse::Handled;
}

// The codes of the errors httplib answers itself (before any route runs).
std::pair<std::string, std::string> status_code_and_message(int status, const Request& req) {
  switch (status) {
    case 400:
      return {"bad_request", "malformed HTTP request"};
    case 404:
      return {"not_found", "no route " + req.method + " " + req.path};
    case 408:
      return {"timeout", "the request did not arrive in time"};
    case 413:
      return {"too_large", req.get_header_value("Content-Type").find("x-www-form-urlencoded") != std::string::npos
                               ? "form-urlencoded bodies are limited to 8 kB: send JSON with "
                                 "'Content-Type: application/json'"
                               : "the request is too large"};
    case 414:
      return {"too_large", "the request line is too long"};
    case 415:
      return {"unsupported_media_type", "unsupported Content-Type or Content-Encoding"};
    case 416:
      return {"bad_request", "bad Range header"};
    case 431:
      return {"too_large", "the request's headers are too large"};
    case 501:
      return {"not_implemented", "the request needs something this server does not do"};
    case 503:
      return {"unavailable", "the server cannot take this request now"};
    default:
      return {status >= 500 ? "internal" : "bad_request", "HTTP status " + std::to_string(status)};
  }
}

}  // namespace

void HttpApiOptions::check() const {
  ORBATLAS_CHECK(max_body_bytes > 0, "http: max_body_bytes must be > 0");
  ORBATLAS_CHECK(max_upload_bytes > 0, "http: max_upload_bytes must be > 0");
  ORBATLAS_CHECK(token.empty() || clients.open(), "http: a token or a clients file, not both");
  for (const auto& [from, _] : redactions) ORBATLAS_CHECK(!from.empty(), "http: a redaction of the empty text");
}

void install_http_api(httplib::Server& server, AtlasService& service, const HttpApiOptions& options, UploadJobs* jobs) {
  options.check();
  const HttpApiOptions opts = options;
  auto context = std::make_shared<ErrorContext>();
  context->redactions = options.redactions;
  auto table = std::make_shared<RouteTable>();
  auto access = std::make_shared<ApiAccess>(options.token.empty() ? options.clients
                                                                  : ClientCredentials::single_token(options.token));
  Router router(server, context, table);

  // SO_REUSEADDR only: httplib's default adds SO_REUSEPORT, with which a second
  // server on the same port starts silently and the kernel splits the clients.
  server.set_socket_options([](socket_t sock) {
    int yes = 1;
    ::setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  });
  server.set_pre_routing_handler([opts, access](const Request& req, Response& res) {
    if (opts.on_request_start) opts.on_request_start(req.path);
    if (!access->open() && req.path != "/healthz" && !is_viewer_file(req.path)) {
      const std::optional<ApiClient> client = access->client_of(req);
      if (!client) {
        res.set_header("WWW-Authenticate", "Bearer");
        return refuse(
            res, 401, "unauthorized",
            req.has_header("Authorization") ? "wrong token" : "this server needs 'Authorization: Bearer <token>'");
      }
      if (!role_allows(client->role, req.method, req.path))
        return refuse(res, 403, "forbidden",
                      "client '" + client->name + "' (" + client_role_name(client->role) + ") may not " + req.method +
                          " " + req.path.substr(0, 100));
    }
    // One length, said once: two Content-Length headers (or one next to a
    // chunked encoding) are how requests are smuggled past proxies.
    const std::size_t lengths = req.get_header_value_count("Content-Length");
    if (lengths > 1) return refuse(res, 400, "bad_request", "the request has more than one Content-Length header");
    if (lengths == 1 && req.has_header("Transfer-Encoding"))
      return refuse(res, 400, "bad_request", "the request has both Content-Length and Transfer-Encoding");
    // One Transfer-Encoding, and only `chunked` (in any case); no
    // Content-Encoding: the body limits apply to the bytes as they arrive, and
    // an inflated body could be any size.
    const std::size_t encodings = req.get_header_value_count("Transfer-Encoding");
    const std::string transfer = lower_trimmed(req.get_header_value("Transfer-Encoding"));
    const bool chunked = encodings == 1 && transfer == "chunked";
    if (encodings > 1 || (encodings == 1 && !chunked))
      return refuse(res, 501, "not_implemented",
                    "Transfer-Encoding '" + req.get_header_value("Transfer-Encoding").substr(0, 40) +
                        "' is not supported (only one 'chunked')");
    if (req.has_header("Content-Encoding")) {
      const std::string content = lower_trimmed(req.get_header_value("Content-Encoding"));
      if (req.get_header_value_count("Content-Encoding") > 1 || (content != "identity" && !content.empty()))
        return refuse(res, 415, "unsupported_media_type",
                      "Content-Encoding '" + req.get_header_value("Content-Encoding").substr(0, 40) +
                          "' is not accepted: send the body uncompressed");
    }
    const std::string length = req.get_header_value("Content-Length");
    std::uint64_t bytes = 0;
    if (lengths == 1) {
      const auto parsed = parse_integer<std::uint64_t>(length);
      if (!parsed) return refuse(res, 400, "bad_request", "Content-Length is not a number");
      bytes = *parsed;
    }
    const bool upload = req.path == "/v1/uploads";
    if (upload) {
      if (bytes > opts.max_upload_bytes)
        return refuse(
            res, 413, "too_large",
            "the upload has " + length + " bytes; uploads are limited to " + std::to_string(opts.max_upload_bytes));
    } else {
      if (chunked)
        return refuse(res, 411, "length_required",
                      "send this request with a Content-Length (chunked bodies are for uploads)");
      if (bytes > opts.max_body_bytes)
        return refuse(
            res, 413, "too_large",
            "the body has " + length + " bytes; this route takes at most " + std::to_string(opts.max_body_bytes));
    }
    return HandlerResponse::Unhandled;
  });
  // Errors httplib produces itself (no route, a body over its limit...) get a
  // JSON body with a documented code; a known path with another method is 405.
  server.set_error_handler(httplib::Server::HandlerWithResponse([table](const Request& req, Response& res) {
    if (!res.body.empty()) return HandlerResponse::Unhandled;
    if (res.status == 404) {
      const std::vector<std::string> methods = table->methods_for(req.path);
      if (!methods.empty()) {
        std::string allow;
        for (const auto& m : methods) allow += (allow.empty() ? "" : ", ") + m;
        res.set_header("Allow", allow);
        reply_error(res, 405, "method_not_allowed", req.method + " " + req.path + ": this route takes " + allow);
        return HandlerResponse::Handled;
      }
    }
    const auto [code, message] = status_code_and_message(res.status, req);
    reply_error(res, res.status, code, message);
    return HandlerResponse::Handled;
  }));
  server.set_logger([opts, access](const Request& req, const Response& res) {
    access->count(req, res.status);
    if (opts.log_requests) {
      const auto client = access->open() ? std::nullopt : access->client_of(req);
      log_info(req.method + " " + req.path + " -> " + std::to_string(res.status) +
               (access->open() ? ""
                : client       ? " (client " + client->name + ", " + client_role_name(client->role) + ")"
                               : " (no client)"));
    }
    if (opts.on_request_end) opts.on_request_end();
  });
  router.get("/healthz", ([&service](const Request&, Response& res) { reply_json(res, to_json(service.health())); }));
  router.get("/metrics", ([&service, jobs, opts, access](const Request&, Response& res) {
               std::vector<prometheus::MetricFamily> families = service.metrics();
               const auto add = [&families](std::vector<prometheus::MetricFamily> more) {
                 families.insert(families.end(), std::make_move_iterator(more.begin()),
                                 std::make_move_iterator(more.end()));
               };
               if (opts.extra_metrics) add(opts.extra_metrics());
               if (jobs) add(jobs->metrics());
               add(access->metrics());
               res.set_content(prometheus::TextSerializer().Serialize(families), "text/plain; version=0.0.4");
             }));
  install_session_routes(router, service, access);
  install_map_routes(router, service);
  install_viewer_routes(router, service, options);
  install_upload_routes(router, service, jobs, options.max_upload_bytes);
}

}  // namespace orbatlas
