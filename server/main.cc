// orbatlas-server: loads an atlas database, serves the HTTP API v1 on it,
// checkpoints while running, and on SIGTERM / SIGINT stops taking requests,
// finishes the live sessions and writes a final durable checkpoint.
#include <signal.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <fstream>
#include <iostream>
#include <sstream>
#include <thread>

#include "client/effective_options.h"
#include "core/common/error.h"
#include "core/common/log.h"
#include "core/persistence/atlas_location.h"
#include "core/server/atlas_service.h"
#include "server/http/guarded_http_server.h"
#include "server/http/http_api.h"
#include "server/http/tls_context.h"
#include "core/server/upload_jobs.h"

// Last: <httplib.h> pulls in <resolv.h>, whose macro _res breaks Eigen's headers.
#include <httplib.h>

namespace {

struct Listen {
  std::string host = "127.0.0.1";
  int port = 8080;
};

Listen parse_listen(const std::string& text) {
  const auto colon = text.rfind(':');
  ORBATLAS_CHECK(colon != std::string::npos && colon > 0, "--listen takes HOST:PORT, got '" << text << "'");
  Listen l;
  l.host = text.substr(0, colon);
  try {
    std::size_t used = 0;
    l.port = std::stoi(text.substr(colon + 1), &used);
    ORBATLAS_CHECK(used == text.size() - colon - 1, "");
  } catch (const std::exception&) {
    throw orbatlas::Error("--listen: bad port in '" + text + "'");
  }
  ORBATLAS_CHECK(l.port >= 0 && l.port <= 65535, "--listen: port " << l.port << " is out of range");
  return l;
}

// The folder for uploads: --work-dir, or "<db>.work" beside an SQLite file.
std::filesystem::path upload_work_dir(const std::string& db, const std::string& work_dir) {
  if (!work_dir.empty()) return work_dir;
  if (orbatlas::is_postgres_location(db))
    throw orbatlas::Error("--db " + orbatlas::location_for_messages(db) +
                          " is a PostgreSQL database: give --work-dir, the folder for uploads being processed that "
                          "every replica of the atlas reaches at the same path");
  return db + ".work";
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"orbatlas map server: stereo SLAM sessions, a persistent atlas and relocalisation over HTTP"};
  orbatlas::AtlasServiceOptions service_options;
  std::string listen_text = "127.0.0.1:8080";
  std::string token;
  std::string port_file;
  std::size_t max_body_mb = 64;
  std::uint64_t max_upload_gb = 32;
  orbatlas::UploadJobOptions job_options;
  int threads = 0;  // 0: from --max-sessions (below)
  bool log_requests = false;
  std::string work_dir;
  app.add_option("--db", service_options.db,
                 "Atlas database: an SQLite file (created when missing) or a PostgreSQL database given as "
                 "postgresql://[user[:password]@]host[:port]/dbname (migrated when empty)")
      ->required();
  app.add_option("--work-dir", work_dir,
                 "Folder for uploads being processed, emptied at start (default: <db>.work beside an SQLite file); "
                 "required with a PostgreSQL --db: then one folder all replicas share, not emptied");
  app.add_option("--listen", listen_text, "HOST:PORT to listen on (port 0: any free port)")->capture_default_str();
  app.add_option("--token", token,
                 "Require 'Authorization: Bearer TOKEN' on every route but /healthz (visible in ps: prefer "
                 "--token-file or the environment variable)")
      ->envname("ORBATLAS_TOKEN");
  std::string tls_cert, tls_key;
  app.add_option("--tls-cert", tls_cert, "Serve HTTPS with this certificate chain (PEM; with --tls-key)")
      ->check(CLI::ExistingFile);
  app.add_option("--tls-key", tls_key, "The private key of --tls-cert (PEM)")->check(CLI::ExistingFile);
  std::string clients_file;
  app.add_option("--clients", clients_file,
                 "Clients file: one 'name role sha256:<hex>' per line, roles reader, device, operator (docs/api.md); "
                 "every route but /healthz then needs one of their tokens")
      ->check(CLI::ExistingFile);
  std::string token_file;
  app.add_option("--token-file", token_file, "Read the token from this file's first line (instead of --token)")
      ->check(CLI::ExistingFile);
  app.add_option("--workers", job_options.workers, "Background workers processing uploaded recordings")
      ->capture_default_str()
      ->check(CLI::Range(1, 64));
  app.add_option("--max-sessions", service_options.max_live_sessions,
                 "Live sessions at most (mapping sessions share a local-mapping thread per map)")
      ->capture_default_str();
  app.add_option("--max-upload-gb", max_upload_gb, "Largest upload")->capture_default_str();
  app.add_option("--threads", threads,
                 "HTTP worker threads (0: 2 x --max-sessions + 4, so that every live session's connection can "
                 "wait between frames and requests still find a free thread)")
      ->capture_default_str()
      ->check(CLI::Range(0, 256));
  app.add_option("--max-body-mb", max_body_mb, "Largest request body (frames, localisation)")->capture_default_str();
  app.add_option("--config-dir", service_options.config_dir, "Folder of named configs (default: the shipped ones)");
  app.add_option("--vocabulary", service_options.vocabulary, "ORB vocabulary (default: the shipped one)");
  app.add_option("--checkpoint-keyframes", service_options.checkpoints.every_keyframes,
                 "Checkpoint after this many new keyframes")
      ->capture_default_str();
  app.add_option("--checkpoint-seconds", service_options.checkpoints.every_seconds, "and at least this often")
      ->capture_default_str();
  app.add_option("--port-file", port_file, "Write the port listened on to this file once listening (tests, scripts)");
  app.add_flag("--log-requests", log_requests, "One log line per request");
  app.add_option("--idle-timeout", service_options.idle_timeout_s,
                 "Finish a live session after this many seconds without a frame (its data is stored; 0: never)")
      ->capture_default_str();
  app.add_option("--finish-refinement-wait", service_options.finish_refinement_wait_s,
                 "Seconds a stereo session that ends in a map other sessions mapped too waits for a global BA of it "
                 "(when the map grew since its last one), so its trajectory at the finish has it (0: none)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 3600.0));
  app.add_option("--background-nice", service_options.background_nice,
                 "Nice value (0-19) of local mapping, loop closing and map merging; above 0 the sessions' tracking is "
                 "served first on a loaded machine, mapping takes the rest (0: all alike)")
      ->capture_default_str()
      ->check(CLI::Range(0, 19));
  app.add_option("--max-maps-wait-ms", service_options.max_maps_wait_ms,
                 "A real-time session's frame (max_lag_s) waits at most this long for the maps while a merge, loop "
                 "correction or global BA result is applied; past it the reply is untracked, maps_busy (0: no bound)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 10000.0));
  bool serial_stereo = false;
  app.add_flag("--serial-stereo-frontend", serial_stereo,
               "Extract a stereo frame's two images one after the other on the session's thread instead of the right "
               "one on a second thread (no hand-over between threads when every core is busy)");
  orbatlas::ConnectionLimits limits;
  app.add_option("--header-timeout", limits.header_timeout_s,
                 "Seconds a request's line and headers may take once it started")
      ->capture_default_str();
  app.add_option("--body-timeout", limits.body_timeout_s,
                 "Seconds the body of a request may take (not uploads: each of their reads is bounded)")
      ->capture_default_str();
  double min_body_rate_kib = limits.min_body_rate_bytes_s / 1024.0;
  app.add_option("--min-body-rate-kib", min_body_rate_kib,
                 "KiB/s a request's body must at least arrive at, after a grace of the header timeout (0: none)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1e6));
  bool insecure = false;
  app.add_flag("--insecure", insecure, "Allow listening on a non-loopback address without --token");
  bool no_merging = false, no_live_merging = false, no_join_at_start = false;
  app.add_option("--replica-url", service_options.replica.url,
                 "Where other replicas of a shared PostgreSQL atlas reach this server's API (listed by GET "
                 "/v1/replicas; default: http://HOST:PORT of --listen)");
  app.add_option("--lease-s", service_options.replica.lease_s,
                 "Seconds after which replicas of a shared PostgreSQL atlas count this server dead when it has not "
                 "renewed its lease (it renews every third of it)")
      ->capture_default_str();
  app.add_flag("--no-merging", no_merging, "Never merge maps (not live, not when a session finishes)");
  app.add_flag("--no-live-merging", no_live_merging, "Merge a session's maps only when it finishes, not while it runs");
  app.add_flag("--no-join-at-start", no_join_at_start,
               "A mapping session starts a map of its own at its first frame, even where a map knows the place");
  app.set_config("--config", "",
                 "Read options from this file (TOML: one 'name = value' per option, as the flags are named, e.g. "
                 "max-sessions = 4); flags given on the command line override it");
  CLI11_PARSE(app, argc, argv);
  limits.min_body_rate_bytes_s = min_body_rate_kib * 1024.0;
  if (!token_file.empty()) {
    if (!token.empty()) {
      std::cerr << "orbatlas-server: give --token or --token-file, not both\n";
      return 2;
    }
    std::ifstream in(token_file);
    std::getline(in, token);
    while (!token.empty() && (token.back() == '\r' || token.back() == ' ' || token.back() == '\t')) token.pop_back();
    if (token.empty()) {
      std::cerr << "orbatlas-server: --token-file " << token_file << ": no token on its first line\n";
      return 2;
    }
  }
  service_options.merge_maps = !no_merging;
  service_options.live_merging = !no_live_merging;
  service_options.start_in_stored_maps = !no_join_at_start;
  service_options.slam.parallel_stereo_frontend = !serial_stereo;

  // Signals go to one thread that asks the server to stop (no handler state).
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  try {
    const Listen listen = parse_listen(listen_text);
    const bool loopback = listen.host == "127.0.0.1" || listen.host == "localhost" || listen.host == "::1" ||
                          listen.host.rfind("127.", 0) == 0;
    if (!token.empty() && !clients_file.empty())
      throw orbatlas::Error("give --token (one client) or --clients (several), not both");
    const orbatlas::ClientCredentials clients =
        clients_file.empty() ? orbatlas::ClientCredentials() : orbatlas::ClientCredentials::from_file(clients_file);
    if (!loopback && token.empty() && clients.open() && !insecure)
      throw orbatlas::Error("--listen " + listen_text +
                            " reaches other machines: give --token (every route but /healthz then needs it), or "
                            "--insecure to serve without one");
    if (!loopback && tls_cert.empty())
      orbatlas::log_warn("--listen " + listen_text +
                         " reaches other machines over plain HTTP: tokens and data cross the network in the clear "
                         "(--tls-cert and --tls-key serve HTTPS)");
    if (threads == 0) threads = static_cast<int>(std::min<std::size_t>(256, 2 * service_options.max_live_sessions + 4));
    ORBATLAS_CHECK(threads >= 2, "--threads must be 0 (automatic) or at least 2");
    orbatlas::log_info("options in effect:\n" + orbatlas::effective_options_text(app) +
                       "  (HTTP threads in use: " + std::to_string(threads) + ")");
    job_options.work_dir = upload_work_dir(service_options.db.string(), work_dir);  // before the database is touched
    orbatlas::AtlasService service(service_options);
    orbatlas::UploadJobs jobs(service, job_options);
    // At most half the HTTP threads wait for slow or idle clients: the others
    // stay free for requests that arrive whole (health checks, frames).
    limits.max_waiting = std::max(1, threads / 2);
    if (tls_cert.empty() != tls_key.empty()) throw orbatlas::Error("--tls-cert and --tls-key go together");
    const auto tls = tls_cert.empty() ? nullptr : std::make_shared<const orbatlas::TlsContext>(tls_cert, tls_key);
    const std::string scheme = tls ? "https://" : "http://";
    orbatlas::GuardedHttpServer server(limits, tls);
    server.new_task_queue = [threads] { return new httplib::ThreadPool(static_cast<std::size_t>(threads)); };
    server.set_payload_max_length(max_upload_gb << 30);  // other routes: max_body_bytes, checked per request
    server.set_tcp_nodelay(true);
    orbatlas::HttpApiOptions api_options;
    api_options.token = token;
    api_options.clients = clients;
    api_options.max_body_bytes = max_body_mb << 20;
    api_options.max_upload_bytes = max_upload_gb << 30;
    api_options.log_requests = log_requests;
    api_options.redactions = orbatlas::server_path_redactions(service);
    api_options.extra_metrics = [&server] { return server.metrics(); };
    orbatlas::install_http_api(server, service, api_options, &jobs);

    const int port = listen.port == 0 ? server.bind_to_any_port(listen.host)
                                      : (server.bind_to_port(listen.host, listen.port) ? listen.port : -1);
    ORBATLAS_CHECK(port > 0, "cannot listen on " << listen.host << ":" << listen.port
                                                 << " (in use, or not an address of this machine)");
    if (!port_file.empty()) {
      std::ofstream out(port_file);
      out << port << "\n";
    }
    orbatlas::log_info(
        "listening on " + scheme + listen.host + ":" + std::to_string(port) +
        (token.empty() && clients.open()
             ? ""
             : " (bearer token required; " + std::to_string(std::max<std::size_t>(1, clients.size())) + " client(s))"));
    if (service_options.replica.url.empty()) {
      try {
        service.replica_url(scheme + listen.host + ":" + std::to_string(port));
      } catch (const std::exception& e) {
        orbatlas::log_warn(std::string("cannot record this replica's URL: ") + e.what());
      }
    }

    std::thread signal_thread([&] {
      int received = 0;
      sigwait(&signals, &received);
      orbatlas::log_info(std::string("signal ") + (received == SIGINT ? "SIGINT" : "SIGTERM") +
                         ": stopping (live sessions are finished and stored)");
      server.stop();
    });
    server.listen_after_bind();
    // listen_after_bind returned: either the signal thread stopped it, or it failed.
    if (server.is_running()) server.stop();
    pthread_kill(signal_thread.native_handle(), SIGTERM);  // wakes sigwait if no signal came
    signal_thread.join();
    jobs.stop();  // a running upload ends at its next frame; its session is stored below
    service.shutdown();
    orbatlas::log_info("atlas stored; bye");
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "orbatlas-server: " << e.what() << "\n";
    return 1;
  }
}
