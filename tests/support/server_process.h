#pragma once
// orbatlas-server as a child process, for the tests that kill it, restart it
// and run several of it over one database (replicas): the process, its log,
// and a session streamed to it. Needs ORBATLAS_SERVER_BINARY (test_server).
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "client/api/server_client.h"
#include "tests/support/slam_test_clip.h"

extern char** environ;

namespace orbatlas::test {

// orbatlas-server as a child process, its log appended to a file.
class ServerProcess {
 public:
  using Clock = std::chrono::steady_clock;

  // `db`: an SQLite file or a postgresql:// URI.
  ServerProcess(const std::string& db, const std::filesystem::path& log,
                const std::vector<std::string>& extra_args = {}) {
    port_file_ = log.string() + ".port";
    std::filesystem::remove(port_file_);
    std::vector<std::string> args = {ORBATLAS_SERVER_BINARY,
                                     "--db",
                                     db,
                                     "--listen",
                                     "127.0.0.1:0",
                                     "--port-file",
                                     port_file_.string(),
                                     "--checkpoint-keyframes",
                                     "2",
                                     "--checkpoint-seconds",
                                     "0.2"};
    args.insert(args.end(), extra_args.begin(), extra_args.end());
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
    const int rc = posix_spawn(&pid_, argv[0], &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    if (rc != 0) throw std::runtime_error("cannot start " + args[0]);
  }
  ~ServerProcess() {
    kill();
    std::filesystem::remove(port_file_);
  }

  // The URL once listening; empty when the server exited or took too long.
  std::string wait_until_listening() {
    for (const auto until = Clock::now() + std::chrono::seconds(30); Clock::now() < until;) {
      std::ifstream in(port_file_);
      int port = 0;
      if (in >> port && port > 0) return "http://127.0.0.1:" + std::to_string(port);
      int status = 0;
      if (::waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = -1;
        return {};
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return {};
  }

  // SIGTERM: a clean stop (the final checkpoint); waits for the exit.
  void terminate() {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGTERM);
    int status = 0;
    ::waitpid(pid_, &status, 0);
    pid_ = -1;
  }

  void kill() {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGKILL);
    int status = 0;
    ::waitpid(pid_, &status, 0);
    pid_ = -1;
  }

 private:
  pid_t pid_ = -1;
  std::filesystem::path port_file_;
};

inline std::string log_text(const std::filesystem::path& log) {
  std::ifstream in(log);
  return std::string((std::istreambuf_iterator<char>(in)), {});
}

// Streams a clip's stereo frames as one session of `client`'s server and finishes it; returns its id.
inline std::uint64_t stream_stereo_session(ServerClient& client, const std::filesystem::path& clip,
                                           const std::string& name) {
  const std::uint64_t id = client.create_session("euroc/stereo", name);
  for (const auto& f : stereo_frames(clip))
    client.post_frame(id, f.t_ns, cv::imread(f.left.string(), cv::IMREAD_GRAYSCALE),
                      cv::imread(f.right.string(), cv::IMREAD_GRAYSCALE));
  client.finish_session(id);
  return id;
}

// The map a session's last frame is in.
inline std::uint64_t map_of_session(ServerClient& client, std::uint64_t session) {
  return client.get_json("/v1/sessions/" + std::to_string(session))["map"].get<std::uint64_t>();
}

// The server's maps once it lists exactly one (waits up to 120 s; the last list otherwise).
inline nlohmann::json maps_once_one(ServerClient& client) {
  using Clock = std::chrono::steady_clock;
  nlohmann::json maps;
  for (const auto until = Clock::now() + std::chrono::seconds(120); Clock::now() < until;) {
    maps = client.get_json("/v1/maps")["maps"];
    if (maps.size() == 1) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return maps;
}

}  // namespace orbatlas::test
