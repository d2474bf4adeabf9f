#pragma once
// An in-process map server on a free loopback port for the HTTP tests: the
// service, the API and a thread running the listener. Destroying it stops the
// listener and shuts the service down (final checkpoint), as SIGTERM does.
#include <chrono>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>
#include <unistd.h>

#include "client/api/dataset_streamer.h"
#include "client/api/server_client.h"
#include "core/server/atlas_service.h"
#include "server/http/guarded_http_server.h"
#include "server/http/http_api.h"
#include "core/server/upload_jobs.h"

// Last: <httplib.h> pulls in <resolv.h>, whose macro _res breaks Eigen's headers.
#include <httplib.h>

namespace orbatlas::test {

// Streaming a recorded clip, without the progress line.
inline StreamOptions stream_options(const std::filesystem::path& clip) {
  StreamOptions o;
  o.dataset = clip;
  o.show_progress = false;
  return o;
}

inline AtlasServiceOptions server_options(const std::filesystem::path& db) {
  AtlasServiceOptions o;
  o.db = db;
  return o;
}

class TestServer {
 public:
  // `tls`: the server speaks HTTPS with it (url() is then https://).
  explicit TestServer(AtlasServiceOptions service_options, HttpApiOptions api = {}, ConnectionLimits limits = {},
                      int threads = 8, std::shared_ptr<const TlsContext> tls = nullptr)
      : service_(std::make_unique<AtlasService>(std::move(service_options))),
        jobs_(std::make_unique<UploadJobs>(*service_, UploadJobOptions{service_->db_path().string() + ".work", 1, 4})),
        http_(limits, std::move(tls)) {
    http_.set_payload_max_length(api.max_body_bytes * 4);
    http_.set_tcp_nodelay(true);
    if (api.redactions.empty()) api.redactions = server_path_redactions(*service_);
    api.extra_metrics = [this] { return http_.metrics(); };
    http_.new_task_queue = [threads] { return new httplib::ThreadPool(static_cast<std::size_t>(threads)); };
    install_http_api(http_, *service_, api, jobs_.get());
    port_ = http_.bind_to_any_port("127.0.0.1");
    thread_ = std::thread([this] { http_.listen_after_bind(); });
    for (int i = 0; i < 500 && !http_.is_running(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  ~TestServer() {
    http_.stop();
    thread_.join();
    jobs_->stop();
    service_->shutdown();
  }
  TestServer(const TestServer&) = delete;
  TestServer& operator=(const TestServer&) = delete;

  std::string url() const { return (http_.tls() ? "https://127.0.0.1:" : "http://127.0.0.1:") + std::to_string(port_); }
  AtlasService& service() { return *service_; }
  const GuardedHttpServer& http() const { return http_; }

 private:
  std::unique_ptr<AtlasService> service_;
  std::unique_ptr<UploadJobs> jobs_;
  GuardedHttpServer http_;
  int port_ = 0;
  std::thread thread_;
};

// A fresh database path under /tmp, removed with its WAL files at the end.
struct TempDbPath {
  std::filesystem::path path;
  explicit TempDbPath(const std::string& name)
      : path(std::filesystem::temp_directory_path() /
             ("orbatlas_test_server_" + name + "_" + std::to_string(::getpid()) + ".db")) {
    clean();
  }
  ~TempDbPath() { clean(); }
  void clean() const {
    std::error_code ec;
    for (const char* suffix : {"", "-wal", "-shm", ".lock"}) std::filesystem::remove(path.string() + suffix, ec);
    std::filesystem::remove_all(path.string() + ".work", ec);
  }
};

// Polls GET /v1/jobs/{job} until it is done, failed or cancelled (at most 2 minutes).
inline nlohmann::json wait_for_job(ServerClient& client, std::uint64_t job) {
  for (int i = 0; i < 1200; ++i) {
    const auto status = client.get_json("/v1/jobs/" + std::to_string(job));
    const std::string state = status["state"];
    if (state == "done" || state == "failed" || state == "cancelled") return status;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return client.get_json("/v1/jobs/" + std::to_string(job));
}

}  // namespace orbatlas::test
