#pragma once
// What the HTTP API's route files share (private to server/http): JSON and
// error replies, the guard every handler runs in (service errors become JSON
// replies with no server path in them), the route table that tells a wrong
// method (405) from a wrong path (404), and the routes installed by files of
// their own. docs/api.md describes the routes.
#include <cstdint>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <regex>
#include <string>
#include <utility>
#include <vector>

#include "core/server/service_error.h"
#include "server/http/http_api.h"

// Last: <httplib.h> pulls in <resolv.h>, whose macro _res breaks Eigen's headers.
#include <httplib.h>

namespace orbatlas {

class AtlasService;
class UploadJobs;

namespace http_detail {

using httplib::Request;
using httplib::Response;
using json = nlohmann::json;

void reply_json(Response& res, const json& body, int status = 200);
void reply_error(Response& res, int status, const std::string& code, const std::string& message);

using Redactions = std::vector<std::pair<std::string, std::string>>;
std::string redacted(std::string message, const Redactions& redactions);

// Set once by install_http_api, read by every handler (the options outlive the server).
struct ErrorContext {
  Redactions redactions;
};

int http_status(ServiceErrorKind kind);  // docs/api.md, "Errors"

// Every handler runs inside this: service errors become JSON replies, with no
// server path in their messages.
void run_guarded(const ErrorContext& context, const Request& req, Response& res, const std::function<void()>& handler);

// The routes, for telling a wrong method (405) from a wrong path (404).
struct RouteTable {
  std::vector<std::pair<std::regex, std::string>> routes;  // pattern, method
  std::vector<std::string> methods_for(const std::string& path) const {
    std::vector<std::string> out;
    for (const auto& [pattern, method] : routes)
      if (std::regex_match(path, pattern) && std::find(out.begin(), out.end(), method) == out.end())
        out.push_back(method);
    return out;
  }
};

// Registers a route on the server and in the table.
class Router {
 public:
  Router(httplib::Server& server, std::shared_ptr<ErrorContext> context, std::shared_ptr<RouteTable> table)
      : server_(server), context_(std::move(context)), table_(std::move(table)) {}

  template <class Handler>
  void get(const std::string& pattern, Handler handler) {
    table_->routes.emplace_back(std::regex(pattern), "GET");
    server_.Get(pattern, guarded(handler));
  }
  template <class Handler>
  void post(const std::string& pattern, Handler handler) {
    table_->routes.emplace_back(std::regex(pattern), "POST");
    server_.Post(pattern, guarded(handler));
  }
  // A POST route that reads its body itself (uploads).
  void post_streaming(const std::string& pattern, httplib::Server::HandlerWithContentReader handler) {
    table_->routes.emplace_back(std::regex(pattern), "POST");
    server_.Post(pattern, std::move(handler));
  }
  const ErrorContext& context() const { return *context_; }

 private:
  template <class Handler>
  auto guarded(Handler handler) {
    return [handler, context = context_](const Request& req, Response& res) {
      run_guarded(*context, req, res, [&] { handler(req, res); });
    };
  }
  httplib::Server& server_;
  std::shared_ptr<ErrorContext> context_;
  std::shared_ptr<RouteTable> table_;
};

// The integer in the route's match group (404 naming `what` when it is none).
std::uint64_t id_from(const Request& req, std::size_t group, const char* what);

// Whether `path` is one of the viewer's files (they hold no data: no token needed).
bool is_viewer_file(const std::string& path);
// The map viewer's files and data routes (http_viewer_routes.cc).
void install_viewer_routes(Router& router, AtlasService& service, const HttpApiOptions& opts);
// Uploads of recordings and their jobs (http_upload_routes.cc).
void install_upload_routes(Router& router, AtlasService& service, UploadJobs* jobs, std::uint64_t max_bytes);

}  // namespace http_detail
}  // namespace orbatlas
