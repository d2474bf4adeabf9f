// Replicas: servers over one PostgreSQL atlas (a throwaway cluster), each
// mapping in maps of its own; one killed, the other takes its maps over, and
// its upload job runs to the end on the other.
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include <chrono>
#include <thread>

#include "client/api/server_client.h"
#include "core/server/replica_registry.h"
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
using test::map_of_session;
using test::ServerProcess;
using test::stream_stereo_session;

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

}  // namespace
}  // namespace orbatlas
