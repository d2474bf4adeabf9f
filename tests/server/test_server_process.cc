// orbatlas-server as a process: its options from a config file (flags win,
// the effective options logged), and a server on a PostgreSQL atlas killed and
// started again with its map.
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include <chrono>
#include <fstream>
#include <regex>
#include <thread>

#include "client/api/server_client.h"
#include "tests/support/requirement.h"
#include "tests/support/server_process.h"
#include "tests/support/server_test_fixture.h"
#include "tests/support/slam_test_clip.h"
#include "tests/support/throwaway_postgres.h"

namespace orbatlas {
namespace {

using Clock = std::chrono::steady_clock;
using json = nlohmann::json;
using test::log_text;
using test::ServerProcess;

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

}  // namespace
}  // namespace orbatlas
