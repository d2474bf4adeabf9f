// The map server killed (SIGKILL) at random moments while clients stream
// sessions and upload recordings, many times over one database. After every
// kill the file must pass SQLite's integrity check and hold no trajectory row
// whose keyframe it does not hold; over the whole run no session or job id may
// be handed out twice, every session a client was given must exist, and no
// upload may finish with data it did not bring (a tar without mav0/ must fail).
#include <fcntl.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <fstream>
#include <random>
#include <regex>
#include <set>
#include <thread>

#include "client/api/server_client.h"
#include "core/archive/tar_writer.h"
#include "core/persistence/sqlite_db.h"
#include "core/server/replica_registry.h"
#include "tests/support/server_test_fixture.h"
#include "tests/support/slam_test_clip.h"
#include "tests/support/throwaway_postgres.h"
#include "tests/support/requirement.h"

extern char** environ;

namespace orbatlas {
namespace {

using Clock = std::chrono::steady_clock;
using json = nlohmann::json;

// ORBATLAS_KILL_ITERATIONS overrides the count (scripts/check/stress.sh-style long runs).
int iterations() {
  const char* text = std::getenv("ORBATLAS_KILL_ITERATIONS");
  return text ? std::max(1, std::atoi(text)) : 50;
}

// orbatlas-server as a child process, its log appended to a file.
class ServerProcess {
 public:
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

std::string log_text(const std::filesystem::path& log) {
  std::ifstream in(log);
  return std::string((std::istreambuf_iterator<char>(in)), {});
}

// Streams a clip's stereo frames as one session of `client`'s server and finishes it; returns its id.
std::uint64_t stream_stereo_session(ServerClient& client, const std::filesystem::path& clip, const std::string& name) {
  const std::uint64_t id = client.create_session("euroc/stereo", name);
  for (const auto& f : test::stereo_frames(clip))
    client.post_frame(id, f.t_ns, cv::imread(f.left.string(), cv::IMREAD_GRAYSCALE),
                      cv::imread(f.right.string(), cv::IMREAD_GRAYSCALE));
  client.finish_session(id);
  return id;
}

// The map a session's last frame is in.
std::uint64_t map_of_session(ServerClient& client, std::uint64_t session) {
  return client.get_json("/v1/sessions/" + std::to_string(session))["map"].get<std::uint64_t>();
}

// The server's maps once it lists exactly one (waits up to 120 s; the last list otherwise).
json maps_once_one(ServerClient& client) {
  json maps;
  for (const auto until = Clock::now() + std::chrono::seconds(120); Clock::now() < until;) {
    maps = client.get_json("/v1/maps")["maps"];
    if (maps.size() == 1) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return maps;
}

std::string tar_without_mav0() {
  std::string tar;
  TarWriter writer([&](const char* d, std::size_t n) { tar.append(d, n); });
  writer.add_directory_entry("not-a-recording/");
  writer.finish();
  return tar;
}

struct Handed {
  std::mutex mutex;
  std::vector<std::uint64_t> sessions, jobs;
  std::set<std::uint64_t> bad_jobs;  // jobs of tars without mav0/
};

// Integrity and references of the file as a killed server left it.
void check_file(const std::filesystem::path& db, int iteration) {
  SqliteDb raw(db);  // recovers the WAL
  SqliteStatement check = raw.prepare("PRAGMA integrity_check");
  ASSERT_TRUE(check.step());
  EXPECT_EQ(check.text(0), "ok") << "after kill " << iteration;
  const std::int64_t dangling = raw.query_int64(
      "SELECT count(*) FROM trajectory t WHERE NOT EXISTS (SELECT 1 FROM keyframes k WHERE k.id = "
      "t.reference_keyframe_id) AND NOT EXISTS (SELECT 1 FROM culled_keyframes c WHERE c.id = "
      "t.reference_keyframe_id)");
  EXPECT_EQ(dangling, 0) << "trajectory rows referencing a keyframe the file does not hold, after kill " << iteration;
}

TEST(ServerKill, RandomKillsDuringStreamsAndUploadsLeaveAConsistentAtlas) {
  const auto clip = test::simulated_clip("MH_01", 40.0, 2.0);
  test::ClipCleanup cleanup{clip};
  const auto frames = test::stereo_frames(clip);
  std::vector<std::pair<cv::Mat, cv::Mat>> images;
  for (const auto& f : frames)
    images.emplace_back(cv::imread(f.left.string(), cv::IMREAD_GRAYSCALE),
                        cv::imread(f.right.string(), cv::IMREAD_GRAYSCALE));
  const std::string bad_tar = tar_without_mav0();
  test::TempDbPath db("kill");
  const std::filesystem::path log = db.path.string() + ".log";
  std::mt19937_64 rng(20261123);
  Handed handed;
  const int kills = iterations();
  int stream_frames = 0;
  const auto t_start = Clock::now();
  for (int iteration = 0; iteration < kills; ++iteration) {
    SCOPED_TRACE("iteration " + std::to_string(iteration));
    ServerProcess server(db.path, log);
    const std::string url = server.wait_until_listening();
    ASSERT_FALSE(url.empty()) << "the server did not start after kill " << iteration << " (log: " << log << ")";
    std::atomic<bool> stop{false};
    std::atomic<int> streamed{0};
    // A live session streaming the clip from a random frame on.
    std::thread streamer([&, start = static_cast<std::size_t>(rng() % (images.size() / 2))] {
      try {
        ServerClient client(url);
        const std::uint64_t id = client.create_session("euroc/stereo", "kill " + std::to_string(iteration));
        {
          std::lock_guard lock(handed.mutex);
          handed.sessions.push_back(id);
        }
        for (std::size_t i = start; i < images.size() && !stop; ++i) {
          client.post_frame(id, frames[i].t_ns, images[i].first, images[i].second);
          ++streamed;
        }
        client.finish_session(id);
      } catch (const std::exception&) {
        // The server was killed under it.
      }
    });
    // Every other iteration an upload: the clip, or a tar without mav0/.
    std::thread uploader([&, kind = rng() % 4] {
      if (kind >= 2) return;
      try {
        ServerClient client(url);
        std::uint64_t job = 0;
        if (kind == 0) {
          job = client.upload(clip, "euroc/stereo", "clip " + std::to_string(iteration));
        } else {
          const auto r =
              client.http().Post("/v1/uploads?name=bad-" + std::to_string(iteration), bad_tar, "application/x-tar");
          if (!r || r->status != 202) return;
          job = json::parse(r->body)["job"].get<std::uint64_t>();
        }
        std::lock_guard lock(handed.mutex);
        handed.jobs.push_back(job);
        if (kind == 1) handed.bad_jobs.insert(job);
      } catch (const std::exception&) {
      }
    });
    // Killed 0.05 .. 1.2 s later: during session creation, streaming, checkpoints, uploads.
    std::this_thread::sleep_for(std::chrono::milliseconds(50 + rng() % 1150));
    server.kill();
    stop = true;
    streamer.join();
    uploader.join();
    stream_frames += streamed.load();
    check_file(db.path, iteration);
    if (HasFailure()) return;
  }

  // No id handed out twice over all the restarts.
  std::set<std::uint64_t> sessions(handed.sessions.begin(), handed.sessions.end());
  std::set<std::uint64_t> jobs(handed.jobs.begin(), handed.jobs.end());
  EXPECT_EQ(sessions.size(), handed.sessions.size()) << "a session id was handed out twice";
  EXPECT_EQ(jobs.size(), handed.jobs.size()) << "a job id was handed out twice";

  // A last, clean start: every session a client was given exists; no tar
  // without mav0/ ever produced a finished job.
  ServerProcess server(db.path, log);
  const std::string url = server.wait_until_listening();
  ASSERT_FALSE(url.empty());
  ServerClient client(url);
  std::set<std::uint64_t> listed;
  const json session_list = client.get_json("/v1/sessions");  // kept: a range over a temporary's member dangles
  for (const auto& s : session_list["sessions"]) listed.insert(s["id"].get<std::uint64_t>());
  for (const std::uint64_t id : sessions) EXPECT_TRUE(listed.count(id)) << "session " << id << " vanished";
  int interrupted = 0;
  const json job_list = client.get_json("/v1/jobs");
  for (const auto& j : job_list["jobs"]) {
    const std::uint64_t id = j["id"].get<std::uint64_t>();
    EXPECT_NE(j["state"], "queued");
    EXPECT_NE(j["state"], "running");
    if (handed.bad_jobs.count(id)) {
      EXPECT_EQ(j["state"], "failed") << j.dump();
    }
    if (j.value("error", "").rfind("interrupted", 0) == 0) ++interrupted;
  }
  server.kill();
  check_file(db.path, kills);
  std::printf(
      "server kills: %d in %.0f s; %zu sessions and %zu upload jobs handed out (all distinct, every session "
      "stored), %d frames streamed, %d jobs reported as interrupted; integrity ok and no dangling trajectory "
      "reference after every kill\n",
      kills, std::chrono::duration<double>(Clock::now() - t_start).count(), sessions.size(), jobs.size(), stream_frames,
      interrupted);
  std::filesystem::remove(log);
}

// orbatlas-server --config FILE: options from a file, flags on the command line
// win, and the options in effect are logged at start (the token's value hidden).
TEST(ServerProcess, ConfigFileIsReadFlagsOverrideItAndTheEffectiveOptionsAreLogged) {
  test::TempDbPath db("server_config");
  const std::filesystem::path config = db.path.string() + ".toml", log = db.path.string() + ".log";
  std::filesystem::remove(log);
  {
    std::ofstream out(config);
    out << "# orbatlas-server options\nmax-sessions = 1\nidle-timeout = 123\ntoken = \"s3cret-token\"\n";
  }
  ServerProcess server(db.path, log, {"--config", config.string(), "--idle-timeout", "77"});
  const std::string url = server.wait_until_listening();
  ASSERT_FALSE(url.empty()) << "the server did not start; its log: " << log;
  ServerClient client(url, "s3cret-token");  // the file's token is required
  const std::uint64_t first = client.create_session("euroc/stereo", "one");
  try {
    client.create_session("euroc/stereo", "two");
    ADD_FAILURE() << "max-sessions = 1 from the file was not applied";
  } catch (const ServerError& e) {
    EXPECT_EQ(e.status(), 503);
  }
  client.finish_session(first);
  ServerClient no_token(url);
  EXPECT_THROW(no_token.get_json("/v1/sessions"), ServerError);
  server.kill();
  std::ifstream in(log);
  const std::string text((std::istreambuf_iterator<char>(in)), {});
  EXPECT_TRUE(std::regex_search(text, std::regex("max-sessions\\s*=\\s*1\\b"))) << text;
  EXPECT_TRUE(std::regex_search(text, std::regex("idle-timeout\\s*=\\s*77\\b"))) << "the flag did not win: " << text;
  EXPECT_EQ(text.find("s3cret-token"), std::string::npos) << "the token was logged";
  std::filesystem::remove(config);
  std::filesystem::remove(log);
}

// `--db postgresql://...`: a session streamed into a server whose
// atlas is a PostgreSQL database (a throwaway cluster), the server killed with
// SIGKILL and started again: the map is there, written by the new replica, and
// new ids continue past any the killed one may have handed out.
TEST(ServerProcess, PostgresDatabaseKeepsTheMapAcrossARestart) {
  std::string why_not;
  const auto cluster = test::ThrowawayPostgres::start(&why_not);
  if (!cluster) ORBATLAS_NEEDS("PostgreSQL (a throwaway cluster): " << why_not);
  cluster->create_database("server_atlas");
  const std::string uri = cluster->uri("server_atlas");
  const auto clip = test::simulated_clip("MH_01", 40.0, 2.0);
  test::ClipCleanup cleanup{clip};
  const auto frames = test::stereo_frames(clip);
  test::TempDbPath files("postgres_server");  // its log, port file and upload folder
  const std::filesystem::path log = files.path.string() + ".log", work = files.path.string() + ".work";
  std::filesystem::remove(log);
  // A short lease: the killed server is seen dead soon after the restart.
  const std::vector<std::string> args = {"--work-dir", work.string(), "--lease-s", "1"};

  std::uint64_t session = 0, first_replica = 0;
  json maps_before;
  {
    ServerProcess server(uri, log, args);
    const std::string url = server.wait_until_listening();
    ASSERT_FALSE(url.empty()) << "the server did not start; its log: " << log_text(log);
    ServerClient client(url);
    // The server is a replica of the database, reachable where it listens.
    const json replicas = client.get_json("/v1/replicas");
    EXPECT_EQ(replicas["backend"], "postgresql") << replicas.dump();
    ASSERT_EQ(replicas["replicas"].size(), 1u) << replicas.dump();
    EXPECT_TRUE(replicas["replicas"][0]["alive"].get<bool>()) << replicas.dump();
    EXPECT_EQ(replicas["replicas"][0]["url"], url) << replicas.dump();
    EXPECT_GT(replicas["replicas"][0]["lease_left_s"].get<double>(), 0.0) << replicas.dump();
    first_replica = replicas["self"].get<std::uint64_t>();
    session = client.create_session("euroc/stereo", "postgres");
    for (const auto& f : frames)
      client.post_frame(session, f.t_ns, cv::imread(f.left.string(), cv::IMREAD_GRAYSCALE),
                        cv::imread(f.right.string(), cv::IMREAD_GRAYSCALE));
    client.finish_session(session);  // stored: a durable checkpoint
    maps_before = client.get_json("/v1/maps")["maps"];
    ASSERT_EQ(maps_before.size(), 1u) << maps_before.dump();
    EXPECT_GE(maps_before[0]["keyframes"].get<int>(), 1) << maps_before.dump();
    EXPECT_GT(maps_before[0]["map_points"].get<int>(), 100) << maps_before.dump();

    server.kill();  // SIGKILL: its connections die, PostgreSQL drops its advisory lock
  }

  ServerProcess server(uri, log, args);
  const std::string url = server.wait_until_listening();
  ASSERT_FALSE(url.empty()) << "the server did not start again; its log: " << log_text(log);
  ServerClient client(url);
  const json maps_after = client.get_json("/v1/maps")["maps"];
  ASSERT_EQ(maps_after.size(), 1u) << maps_after.dump();
  EXPECT_EQ(maps_after[0]["id"], maps_before[0]["id"]);
  EXPECT_EQ(maps_after[0]["keyframes"], maps_before[0]["keyframes"]);
  EXPECT_EQ(maps_after[0]["map_points"], maps_before[0]["map_points"]);
  EXPECT_FALSE(client.trajectory_tum(session).empty());
  // The restarted server is a new replica: it writes the killed one's map from
  // now on, taken at its start or, when the killed one's 1-s lease had not
  // passed yet, by its takeover a lease later.
  const auto taken = [&] {
    const std::string text = log_text(log);
    return text.find("stored map(s) that no live replica writes") != std::string::npos ||
           text.find("took over map(s)") != std::string::npos;
  };
  for (const auto until = Clock::now() + std::chrono::seconds(10); !taken() && Clock::now() < until;)
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_TRUE(taken()) << "the restart did not take the map over: " << log_text(log);
  const std::uint64_t next = client.create_session("euroc/stereo", "after the restart");
  EXPECT_GT(next, session);
  client.finish_session(next);
  // The killed server is still listed, running by its row, but dead: its
  // 1-s lease passed without a renewal.
  json replicas;
  for (int attempt = 0; attempt < 50; ++attempt) {
    replicas = client.get_json("/v1/replicas");
    if (replicas["replicas"].size() == 2 && !replicas["replicas"][0]["alive"].get<bool>()) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  ASSERT_EQ(replicas["replicas"].size(), 2u) << replicas.dump();
  EXPECT_EQ(replicas["replicas"][0]["id"], first_replica) << replicas.dump();
  EXPECT_EQ(replicas["replicas"][0]["state"], "running") << replicas.dump();
  EXPECT_FALSE(replicas["replicas"][0]["alive"].get<bool>()) << replicas.dump();
  EXPECT_LT(replicas["replicas"][0]["lease_left_s"].get<double>(), 0.0) << replicas.dump();
  EXPECT_TRUE(replicas["replicas"][1]["alive"].get<bool>()) << replicas.dump();
  EXPECT_TRUE(replicas["replicas"][1]["self"].get<bool>()) << replicas.dump();
  EXPECT_EQ(replicas["self"], replicas["replicas"][1]["id"]) << replicas.dump();
  server.kill();
  std::filesystem::remove(log);
}

// Two replicas over one PostgreSQL atlas: each maps its own session
// into a map of its own (ids from its own ranges), each reads and localises in
// the map the other made, one is killed with SIGKILL,
// the other takes its map over once its lease has passed (reading it again:
// what the killed one last committed) with its session, maps in it, and a
// server started afterwards finds both maps as the survivor left them.
TEST(ServerProcess, TwoReplicasMapTheirOwnMapsAndOneTakesOverWhenTheOtherDies) {
  std::string why_not;
  const auto cluster = test::ThrowawayPostgres::start(&why_not);
  if (!cluster) ORBATLAS_NEEDS("PostgreSQL (a throwaway cluster): " << why_not);
  cluster->create_database("replicas");
  const std::string uri = cluster->uri("replicas");
  const auto clip_a = test::simulated_clip("MH_01", 40.0, 2.0);
  const auto clip_b = test::simulated_clip("MH_03", 40.0, 2.0);
  test::ClipCleanup cleanup_a{clip_a}, cleanup_b{clip_b};
  test::TempDbPath files("replicas_server");
  const auto log = [&](const std::string& who) {
    return std::filesystem::path(files.path.string() + "." + who + ".log");
  };
  const auto args = [&](const std::string& who) {
    return std::vector<std::string>{"--work-dir", files.path.string() + "." + who + ".work", "--lease-s", "1"};
  };
  const auto keyframes_of = [](const json& maps, std::uint64_t map) {
    for (const auto& m : maps)
      if (m["id"].get<std::uint64_t>() == map) return m["keyframes"].get<int>();
    return -1;
  };

  ServerProcess a(uri, log("a"), args("a"));
  const std::string url_a = a.wait_until_listening();
  ASSERT_FALSE(url_a.empty()) << log_text(log("a"));
  ServerProcess b(uri, log("b"), args("b"));  // a second replica starts: the lock is shared
  const std::string url_b = b.wait_until_listening();
  ASSERT_FALSE(url_b.empty()) << log_text(log("b"));
  ServerClient client_a(url_a), client_b(url_b);
  const json replicas = client_b.get_json("/v1/replicas")["replicas"];
  ASSERT_EQ(replicas.size(), 2u) << replicas.dump();
  const std::uint64_t replica_a = replicas[0]["id"], replica_b = replicas[1]["id"];
  EXPECT_TRUE(replicas[0]["alive"].get<bool>() && replicas[1]["alive"].get<bool>()) << replicas.dump();

  // Each maps a session of its own, at the same time, into a map of its own.
  std::uint64_t session_a = 0, session_b = 0;
  std::thread streaming_a([&] { session_a = stream_stereo_session(client_a, clip_a, "on a"); });
  session_b = stream_stereo_session(client_b, clip_b, "on b");
  streaming_a.join();
  const std::uint64_t map_a = map_of_session(client_a, session_a), map_b = map_of_session(client_b, session_b);
  EXPECT_EQ(map_a >> kReplicaMapIdShift, replica_a);  // ids from each replica's own range
  EXPECT_EQ(map_b >> kReplicaMapIdShift, replica_b);
  EXPECT_EQ(session_a >> kReplicaMapIdShift, replica_a);
  EXPECT_EQ(session_b >> kReplicaMapIdShift, replica_b);
  const int keyframes_a = keyframes_of(client_a.get_json("/v1/maps")["maps"], map_a);
  EXPECT_GE(keyframes_a, 1);
  // a's map was made after b started: b reads it once a's checkpoint changed
  // its version (within a lease), and localises in it (but does not write it).
  const auto until_read = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (keyframes_of(client_b.get_json("/v1/maps")["maps"], map_a) != keyframes_a &&
         std::chrono::steady_clock::now() < until_read)
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  ASSERT_EQ(keyframes_of(client_b.get_json("/v1/maps")["maps"], map_a), keyframes_a) << log_text(log("b"));
  const auto frames_a = test::stereo_frames(clip_a);
  const auto& probe = frames_a[frames_a.size() / 2];
  const json located = client_b.localize("euroc/stereo", cv::imread(probe.left.string(), cv::IMREAD_GRAYSCALE),
                                         cv::imread(probe.right.string(), cv::IMREAD_GRAYSCALE));
  EXPECT_TRUE(located["recognised"].get<bool>()) << located.dump();
  if (located["recognised"].get<bool>()) {
    EXPECT_EQ(located["map"].get<std::uint64_t>(), map_a) << located.dump();
  }

  // And a reads b's map the same way.
  const int keyframes_b_then = keyframes_of(client_b.get_json("/v1/maps")["maps"], map_b);
  while (keyframes_of(client_a.get_json("/v1/maps")["maps"], map_b) != keyframes_b_then &&
         std::chrono::steady_clock::now() < until_read + std::chrono::seconds(5))
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_EQ(keyframes_of(client_a.get_json("/v1/maps")["maps"], map_b), keyframes_b_then) << log_text(log("a"));
  const auto writable_on = [](ServerClient& client, std::uint64_t map) {
    return client.get_json("/v1/maps/" + std::to_string(map))["writable"].get<bool>();
  };
  EXPECT_FALSE(writable_on(client_b, map_a));
  EXPECT_TRUE(writable_on(client_b, map_b));
  a.kill();  // SIGKILL mid-life: its map is nobody's until b takes it over
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  while (!writable_on(client_b, map_a) && std::chrono::steady_clock::now() < until)
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  ASSERT_TRUE(writable_on(client_b, map_a)) << "b did not take a's map over: " << log_text(log("b"));
  const json maps_b = client_b.get_json("/v1/maps")["maps"];
  ASSERT_EQ(keyframes_of(maps_b, map_a), keyframes_a) << "b did not take a's map over: " << maps_b.dump() << "\n"
                                                      << log_text(log("b"));
  EXPECT_NE(log_text(log("b")).find("took over map(s) " + std::to_string(map_a)), std::string::npos)
      << log_text(log("b"));
  // a's session too: listed by b, its trajectory read from the database.
  EXPECT_FALSE(client_b.trajectory_tum(session_a).empty());
  // b maps in a's map now: a session over a's place joins it.
  const std::uint64_t again = stream_stereo_session(client_b, clip_a, "a's place, on b");
  EXPECT_EQ(map_of_session(client_b, again), map_a);
  const int extended = keyframes_of(client_b.get_json("/v1/maps")["maps"], map_a);
  const int keyframes_b = keyframes_of(client_b.get_json("/v1/maps")["maps"], map_b);
  b.terminate();

  // A server started now finds both maps as b left them.
  ServerProcess c(uri, log("c"), args("c"));
  const std::string url_c = c.wait_until_listening();
  ASSERT_FALSE(url_c.empty()) << log_text(log("c"));
  ServerClient client_c(url_c);
  const json maps_c = client_c.get_json("/v1/maps")["maps"];
  EXPECT_EQ(keyframes_of(maps_c, map_a), extended) << maps_c.dump();
  EXPECT_EQ(keyframes_of(maps_c, map_b), keyframes_b) << maps_c.dump();
  EXPECT_EQ(client_c.get_json("/v1/sessions")["sessions"].size(), 3u);
  c.kill();
  for (const char* who : {"a", "b", "c"}) {
    std::filesystem::remove(log(who));
    std::filesystem::remove_all(files.path.string() + "." + who + ".work");
  }
}

// The shared upload queue: two replicas over one PostgreSQL atlas
// and one work folder. Two uploads to a: a's one worker takes the first, b's
// free worker the second; a is SIGKILLed while it runs the first, which b runs
// again, once a's lease has passed, to the end; b owns a's maps then, and
// nothing a stored is lost (its session of the first run stays).
TEST(ServerProcess, AnUploadWhoseReplicaDiesIsFinishedByTheOther) {
  std::string why_not;
  const auto cluster = test::ThrowawayPostgres::start(&why_not);
  if (!cluster) ORBATLAS_NEEDS("PostgreSQL (a throwaway cluster): " << why_not);
  cluster->create_database("uploads");
  const std::string uri = cluster->uri("uploads");
  const auto clip = test::simulated_clip("MH_01", 40.0, 8.0);
  test::ClipCleanup cleanup{clip};
  test::TempDbPath files("shared_uploads");
  const std::string work = files.path.string() + ".work";  // one folder for both
  const auto log = [&](const std::string& who) {
    return std::filesystem::path(files.path.string() + "." + who + ".log");
  };
  const std::vector<std::string> args = {"--work-dir", work, "--lease-s", "1", "--workers", "1", "--no-merging"};
  ServerProcess a(uri, log("a"), args);
  const std::string url_a = a.wait_until_listening();
  ASSERT_FALSE(url_a.empty()) << log_text(log("a"));
  ServerProcess b(uri, log("b"), args);
  const std::string url_b = b.wait_until_listening();
  ASSERT_FALSE(url_b.empty()) << log_text(log("b"));
  ServerClient client_a(url_a), client_b(url_b);
  const std::uint64_t replica_b = client_b.get_json("/v1/replicas")["self"];

  const std::uint64_t first = client_a.upload(clip, "euroc/stereo", "first");
  const std::uint64_t second = client_a.upload(clip, "euroc/stereo", "second");
  const auto job = [&](std::uint64_t id) { return client_b.get_json("/v1/jobs/" + std::to_string(id)); };
  const auto wait_for = [&](std::uint64_t id, const std::string& state, int seconds) {
    json j;
    for (const auto until = Clock::now() + std::chrono::seconds(seconds); Clock::now() < until;) {
      j = job(id);
      if (j["state"] == state) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return j;
  };
  json running;
  for (const auto until = Clock::now() + std::chrono::seconds(30); Clock::now() < until;) {
    running = job(first);
    if (running["state"] == "running" && running.contains("session")) break;  // its session is stored
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ASSERT_EQ(running["state"], "running") << running.dump() << log_text(log("a"));
  a.kill();  // mid-job: the first upload's job starts again on b
  // Generous bounds: a sanitizer build runs the jobs some 20 times slower.
  const json done_first = wait_for(first, "done", 600), done_second = wait_for(second, "done", 600);
  ASSERT_EQ(done_first["state"], "done") << done_first.dump() << "\n" << log_text(log("b"));
  ASSERT_EQ(done_second["state"], "done") << done_second.dump() << "\n" << log_text(log("b"));
  for (const json& j : {done_first, done_second}) {
    EXPECT_EQ(j["frames_done"], j["frames_total"]) << j.dump();
    EXPECT_GT(j["frames_total"].get<int>(), 100) << j.dump();
    // Both ran on b at the end: their sessions are b's.
    EXPECT_EQ(j["session"].get<std::uint64_t>() >> kReplicaMapIdShift, replica_b) << j.dump();
  }
  EXPECT_NE(log_text(log("b")).find("upload job " + std::to_string(first)), std::string::npos) << log_text(log("b"));
  // a's maps (its run of the first upload made one) are b's now, and a's
  // session of that run is kept.
  json maps;
  for (const auto until = Clock::now() + std::chrono::seconds(120); Clock::now() < until;) {
    maps = client_b.get_json("/v1/maps")["maps"];
    bool all = !maps.empty();
    for (const auto& m : maps) all = all && m["writable"].get<bool>();
    if (all) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  for (const auto& m : maps) EXPECT_TRUE(m["writable"].get<bool>()) << maps.dump();
  // b lists a dead replica's sessions once its takeover thread (once per
  // lease) has read them: not necessarily by the time the maps are writable
  // (the whole suite, under load, once saw 2 here).
  json sessions;
  for (const auto until = Clock::now() + std::chrono::seconds(120); Clock::now() < until;) {
    sessions = client_b.get_json("/v1/sessions")["sessions"];
    if (sessions.size() >= 3) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  EXPECT_EQ(sessions.size(), 3u) << sessions.dump() << "\n" << log_text(log("b"));
  b.kill();
  for (const char* who : {"a", "b"}) std::filesystem::remove(log(who));
  std::filesystem::remove_all(work);
}

// Merge work as rows: a maps again, in a map of its own, a place
// b mapped, and b merges a's map into its own map:
// - kNoMergingKilled: a does not merge (--no-merging), so the merge work of
//   its finished session waits in the database; b takes it with a's map once
//   a is killed;
// - kNoMergingAlive: the same with a alive: b asks a for the map once the
//   work waited a lease, and a hands it over;
// - kKilledWhileMapping: a merges, but is killed while its session maps (the
//   session never finishes); b takes a's map over and adopts the session's
//   stored work (the search, merge and global BA its end would have started).
enum class ReplicaA { kNoMergingKilled, kNoMergingAlive, kKilledWhileMapping };

void merge_work_left_by_replica(ReplicaA what) {
  std::string why_not;
  const auto cluster = test::ThrowawayPostgres::start(&why_not);
  if (!cluster) ORBATLAS_NEEDS("PostgreSQL (a throwaway cluster): " << why_not);
  cluster->create_database("merges");
  const std::string uri = cluster->uri("merges");
  // Two flights over one place (as ServerMerging.SessionsOverOnePlaceEndInOneMap...).
  const auto clip_b = test::simulated_clip("MH_01", 46.0, 8.0), clip_a = test::simulated_clip("MH_02", 38.0, 8.0);
  test::ClipCleanup cleanup_a{clip_a}, cleanup_b{clip_b};
  test::TempDbPath files("shared_merges");
  const auto log = [&](const std::string& who) {
    return std::filesystem::path(files.path.string() + "." + who + ".log");
  };
  const auto args = [&](bool merging) {
    std::vector<std::string> a = {"--work-dir", files.path.string() + ".work", "--lease-s", "1"};
    if (!merging) a.push_back("--no-merging");
    return a;
  };
  const auto stream = [](ServerClient& client, const std::filesystem::path& clip, const std::string& name) {
    return map_of_session(client, stream_stereo_session(client, clip, name));
  };
  ServerProcess b(uri, log("b"), args(true));
  const std::string url_b = b.wait_until_listening();
  ASSERT_FALSE(url_b.empty()) << log_text(log("b"));
  ServerClient client_b(url_b);
  const std::uint64_t map_b = stream(client_b, clip_b, "on b");
  ServerProcess a(uri, log("a"), args(what == ReplicaA::kKilledWhileMapping));
  const std::string url_a = a.wait_until_listening();
  ASSERT_FALSE(url_a.empty()) << log_text(log("a"));
  ServerClient client_a(url_a);
  std::uint64_t map_a = 0;
  if (what == ReplicaA::kKilledWhileMapping) {
    const std::uint64_t session = client_a.create_session("euroc/stereo", "the same place, on a, never finished");
    for (const auto& f : test::stereo_frames(clip_a))
      client_a.post_frame(session, f.t_ns, cv::imread(f.left.string(), cv::IMREAD_GRAYSCALE),
                          cv::imread(f.right.string(), cv::IMREAD_GRAYSCALE));
    map_a = map_of_session(client_a, session);
    // Killed once b has read a's map as a last checkpointed it (all its keyframes).
    const auto keyframes_on = [&](ServerClient& client) {
      for (const auto& m : client.get_json("/v1/maps")["maps"])
        if (m["id"].get<std::uint64_t>() == map_a) return m["keyframes"].get<int>();
      return -1;
    };
    const int keyframes_a = keyframes_on(client_a);
    for (const auto until = Clock::now() + std::chrono::seconds(60);
         keyframes_on(client_b) != keyframes_a && Clock::now() < until;)
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    ASSERT_EQ(keyframes_on(client_b), keyframes_a) << log_text(log("b"));
  } else {
    map_a = stream(client_a, clip_a, "the same place, on a");  // b's map is b's: a map of its own
  }
  ASSERT_NE(map_a, map_b);
  if (what != ReplicaA::kNoMergingAlive) a.kill();

  const json maps = maps_once_one(client_b);
  ASSERT_EQ(maps.size(), 1u) << maps.dump() << "\n" << log_text(log("b"));
  EXPECT_EQ(maps[0]["id"].get<std::uint64_t>(), map_b) << maps.dump();  // a's map merged into b's
  const std::string text_b = log_text(log("b"));
  EXPECT_NE(text_b.find("map merging: map " + std::to_string(map_a) + "'s stored merge work taken"), std::string::npos)
      << text_b;
  if (what == ReplicaA::kKilledWhileMapping) {
    EXPECT_NE(text_b.find("while they mapped leave merge work for map(s) " + std::to_string(map_a)), std::string::npos)
        << text_b;
  }
  if (what == ReplicaA::kNoMergingAlive) {
    const std::string text_a = log_text(log("a"));
    EXPECT_NE(text_b.find("asks for map " + std::to_string(map_a) + ": its merge work waits"), std::string::npos);
    EXPECT_NE(text_a.find("handed map " + std::to_string(map_a) + " over to replica"), std::string::npos) << text_a;
    const json on_a = maps_once_one(client_a);
    ASSERT_EQ(on_a.size(), 1u) << on_a.dump() << "\n" << text_a;  // a reads b's merged map
    EXPECT_EQ(on_a[0]["id"].get<std::uint64_t>(), map_b);
    a.kill();
  }
  b.kill();
  for (const char* who : {"a", "b"}) std::filesystem::remove(log(who));
}

TEST(ServerProcess, TheMergeWorkOfADeadReplicaIsDoneByTheReplicaThatTakesItsMapsOver) {
  merge_work_left_by_replica(ReplicaA::kNoMergingKilled);
}

TEST(ServerProcess, TheMergeWorkALiveReplicaLeavesIsDoneByAFreeOneItHandsTheMapTo) {
  merge_work_left_by_replica(ReplicaA::kNoMergingAlive);
}

TEST(ServerProcess, TheSessionAReplicaMappedWhenItDiedIsMergedByTheReplicaThatTakesItsMapOver) {
  merge_work_left_by_replica(ReplicaA::kKilledWhileMapping);
}

// Both replicas live: b's finished session found its place in a's map, so b
// asks for that map, a hands it over (nothing works in it on a) and b merges.
TEST(ServerProcess, TwoLiveReplicasMappingOnePlaceEndInOneMap) {
  std::string why_not;
  const auto cluster = test::ThrowawayPostgres::start(&why_not);
  if (!cluster) ORBATLAS_NEEDS("PostgreSQL (a throwaway cluster): " << why_not);
  cluster->create_database("handover");
  const std::string uri = cluster->uri("handover");
  const auto clip_a = test::simulated_clip("MH_01", 46.0, 8.0), clip_b = test::simulated_clip("MH_02", 38.0, 8.0);
  test::ClipCleanup cleanup_a{clip_a}, cleanup_b{clip_b};
  test::TempDbPath files("shared_handover");
  const auto log = [&](const std::string& who) {
    return std::filesystem::path(files.path.string() + "." + who + ".log");
  };
  const std::vector<std::string> args = {"--work-dir", files.path.string() + ".work", "--lease-s", "1"};
  const auto stream = [](ServerClient& client, const std::filesystem::path& clip, const std::string& name) {
    const std::uint64_t id = stream_stereo_session(client, clip, name);
    return std::pair{id, map_of_session(client, id)};
  };
  ServerProcess a(uri, log("a"), args), b(uri, log("b"), args);
  const std::string url_a = a.wait_until_listening(), url_b = b.wait_until_listening();
  ASSERT_FALSE(url_a.empty()) << log_text(log("a"));
  ASSERT_FALSE(url_b.empty()) << log_text(log("b"));
  ServerClient client_a(url_a), client_b(url_b);
  const auto [session_a, map_a] = stream(client_a, clip_a, "on a");
  // a's own merge work first (nothing to merge with yet: its map is refined), so that b's finds a's map.
  for (const auto until = Clock::now() + std::chrono::seconds(120);
       Clock::now() < until && client_a.get_json("/v1/merges")["refinements_total"].get<std::size_t>() == 0;)
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  ASSERT_EQ(client_a.get_json("/v1/merges")["refinements_total"].get<std::size_t>(), 1u) << log_text(log("a"));
  const auto [session_b, map_b] = stream(client_b, clip_b, "the same place, on b");  // a's map is a's: a map of its own
  ASSERT_NE(map_a, map_b);

  // Both alive: one map in the end, as each of them sees it.
  const json on_b = maps_once_one(client_b);
  ASSERT_EQ(on_b.size(), 1u) << on_b.dump() << "\n" << log_text(log("b")) << "\n" << log_text(log("a"));
  EXPECT_EQ(on_b[0]["id"].get<std::uint64_t>(), map_a) << on_b.dump();  // b's map merged into a's map
  const std::string text_a = log_text(log("a")), text_b = log_text(log("b"));
  EXPECT_NE(text_b.find("asks for map " + std::to_string(map_a)), std::string::npos) << text_b;
  EXPECT_NE(text_a.find("handed map " + std::to_string(map_a) + " over to replica"), std::string::npos) << text_a;
  EXPECT_TRUE(client_b.get_json("/v1/maps/" + std::to_string(map_a))["writable"].get<bool>());
  const json on_a = maps_once_one(client_a);  // a reads what b made of it
  ASSERT_EQ(on_a.size(), 1u) << on_a.dump() << "\n" << log_text(log("a"));
  EXPECT_EQ(on_a[0]["id"].get<std::uint64_t>(), map_a);
  const json map_on_a = client_a.get_json("/v1/maps/" + std::to_string(map_a));
  EXPECT_FALSE(map_on_a["writable"].get<bool>());
  EXPECT_EQ(map_on_a["keyframes"].get<std::size_t>(), on_b[0]["keyframes"].get<std::size_t>()) << map_on_a.dump();
  // Each session (listed by its own replica) ends in the one map.
  EXPECT_EQ(client_a.get_json("/v1/sessions/" + std::to_string(session_a))["map"].get<std::uint64_t>(), map_a);
  EXPECT_EQ(client_b.get_json("/v1/sessions/" + std::to_string(session_b))["map"].get<std::uint64_t>(), map_a);
  a.kill();
  b.kill();
  for (const char* who : {"a", "b"}) std::filesystem::remove(log(who));
}

}  // namespace
}  // namespace orbatlas
