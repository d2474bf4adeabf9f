// The map viewer (docs/viewer.md): its page and scripts, which hold no data
// and need no token, and its data routes, which do.
#include <filesystem>
#include <fstream>
#include <iterator>
#include <regex>
#include <string>
#include <utility>
#include <vector>

#include "core/common/parse_integer.h"
#include "core/server/atlas_service.h"
#include "core/server/viewer_data.h"
#include "wire/service_json.h"
#include "server/http/http_router.h"  // last: it includes <httplib.h>

namespace orbatlas::http_detail {
namespace {

const std::vector<std::pair<std::string, std::string>>& viewer_files() {
  static const std::vector<std::pair<std::string, std::string>> files = {
      {"/", "text/html; charset=utf-8"},
      {"/viewer/app.js", "text/javascript; charset=utf-8"},
      {"/viewer/scene.js", "text/javascript; charset=utf-8"},
      {"/viewer/style.css", "text/css; charset=utf-8"},
      {"/viewer/three.min.js", "text/javascript; charset=utf-8"},
      {"/viewer/OrbitControls.js", "text/javascript; charset=utf-8"}};
  return files;
}

std::filesystem::path viewer_file_path(const std::string& route, const HttpApiOptions& opts) {
  if (route == "/") return opts.viewer_dir / "index.html";
  const std::string name = route.substr(std::string("/viewer/").size());
  if (name == "three.min.js") return opts.three_js_dir / "three.min.js";
  if (name == "OrbitControls.js") return opts.three_js_dir / "examples" / "js" / "controls" / "OrbitControls.js";
  return opts.viewer_dir / name;
}

json pose_view(const Pose3& T) {
  return {{"p", {T.t.x(), T.t.y(), T.t.z()}}, {"q", {T.q.w(), T.q.x(), T.q.y(), T.q.z()}}};
}

}  // namespace

bool is_viewer_file(const std::string& path) {
  for (const auto& [file, _] : viewer_files())
    if (path == file) return true;
  return false;
}

void install_viewer_routes(Router& router, AtlasService& service, const HttpApiOptions& opts) {
  for (const auto& [route, type] : viewer_files()) {
    const std::string escaped = std::regex_replace(route, std::regex(R"([.])"), R"(\.)");
    router.get(escaped, ([route = route, type = type, opts](const Request&, Response& res) {
                 std::ifstream in(viewer_file_path(route, opts), std::ios::binary);
                 if (!in) throw_not_found("the viewer's file " + route + " is not installed on this server");
                 res.set_content(std::string(std::istreambuf_iterator<char>(in), {}), type);
                 res.set_header("Cache-Control", "no-cache");
               }));
  }
  router.get(R"(/v1/maps/(\d+)/keyframes)", ([&service](const Request& req, Response& res) {
               const MapKeyframesView view = map_keyframes_view(service.atlas(), id_from(req, 1, "map"));
               json keyframes = json::array();
               for (const auto& kf : view.keyframes) {
                 json j = pose_view(kf.T_w_c);
                 j["id"] = kf.id;
                 j["parent"] = kf.parent ? json(*kf.parent) : json(nullptr);
                 keyframes.push_back(std::move(j));
               }
               json loops = json::array();
               for (const auto& [a, b] : view.loop_edges) loops.push_back({a, b});
               reply_json(res, {{"map", view.map}, {"keyframes", keyframes}, {"loop_edges", loops}});
             }));
  router.get(R"(/v1/maps/(\d+)/points\.bin)", ([&service](const Request& req, Response& res) {
               std::size_t max_points = 200000;
               if (req.has_param("max")) {
                 const std::string text = req.get_param_value("max");
                 const auto parsed = parse_integer<std::size_t>(text);
                 if (!parsed || *parsed < 1 || *parsed > 5000000)
                   throw_bad_request("max must be a whole number of points in 1..5000000, not '" + text + "'");
                 max_points = *parsed;
               }
               const MapPointCloud cloud = service.map_points(id_from(req, 1, "map"));
               const std::vector<float> xyz = point_buffer(cloud, max_points);
               res.set_header("X-Points-Total", std::to_string(cloud.points.size()));
               res.set_header("X-Points-Sent", std::to_string(xyz.size() / 3));
               res.set_content(std::string(reinterpret_cast<const char*>(xyz.data()), xyz.size() * sizeof(float)),
                               "application/octet-stream");
             }));
  router.get("/v1/live", ([&service](const Request&, Response& res) {
               json sessions = json::array();
               for (const LiveSessionView& v : live_sessions_view(service)) {
                 json j = to_json(v.status);
                 j["pose"] = v.T_w_b ? pose_view(*v.T_w_b) : json(nullptr);
                 j["tracking_p50_ms"] =
                     v.status.tracking_ms.empty() ? json(nullptr) : json(percentiles(v.status.tracking_ms).p50);
                 sessions.push_back(std::move(j));
               }
               reply_json(res, {{"sessions", sessions}});
             }));
}

}  // namespace orbatlas::http_detail
