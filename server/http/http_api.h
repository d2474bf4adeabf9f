#pragma once
// HTTP API v1 of the map server (docs/api.md): routes on a cpp-httplib server
// calling an AtlasService. Every error is a 4xx/5xx reply with the JSON body
// {"error": {"code": "...", "message": "..."}}.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <prometheus/metric_family.h>
#include <string>
#include <utility>
#include <vector>

#include "core/common/data_paths.h"
#include "server/http/client_credentials.h"

namespace httplib {
class Server;
}

namespace orbatlas {

class AtlasService;
class UploadJobs;

struct HttpApiOptions {
  // Who may call (server/http/client_credentials.h): the clients of a clients
  // file, or one `token` (the client "token", an operator); neither: open.
  // Every route but /healthz and the viewer's files then needs a bearer token.
  ClientCredentials clients;
  std::string token;
  std::size_t max_body_bytes = 64u << 20;        // frames, localisation, JSON
  std::uint64_t max_upload_bytes = 32ull << 30;  // POST /v1/uploads (the server's payload limit must allow it)
  bool log_requests = false;                     // one line per request on stderr
  // Text replaced in every error message a client sees (server file paths:
  // the database, its work folder, the config folder).
  std::vector<std::pair<std::string, std::string>> redactions;
  // Called on the connection's thread once a request's headers are read (with
  // its path), and once its reply is written (connection_guard.h).
  std::function<void(const std::string& path)> on_request_start;
  std::function<void()> on_request_end;
  // More metrics for /metrics (the HTTP server's connection figures).
  std::function<std::vector<prometheus::MetricFamily>()> extra_metrics;

  // The map viewer's page (GET /) and three.js (libjs-three), served from here.
  std::filesystem::path viewer_dir = shipped_viewer_dir();
  std::filesystem::path three_js_dir = ::orbatlas::three_js_dir();

  // Throws Error naming the first value out of range.
  void check() const;
};

// The redactions for a service's paths (its database, work folder, configs).
std::vector<std::pair<std::string, std::string>> server_path_redactions(const AtlasService& service);

// `service` and `jobs` must outlive `server`; without `jobs` uploads are refused (503).
void install_http_api(httplib::Server& server, AtlasService& service, const HttpApiOptions& options,
                      UploadJobs* jobs = nullptr);

}  // namespace orbatlas
