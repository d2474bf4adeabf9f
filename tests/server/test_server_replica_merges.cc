// Replicas merging maps: merge work a replica left (killed, or not merging)
// done by the one that takes its map, and two live replicas whose sessions
// mapped one place ending in one map.
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include <chrono>
#include <thread>
#include <utility>

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
using test::map_of_session;
using test::maps_once_one;
using test::ServerProcess;
using test::stream_stereo_session;

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
