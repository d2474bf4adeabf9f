// The map server killed (SIGKILL) at random moments while clients stream
// sessions and upload recordings, many times over one database. After every
// kill the file must pass SQLite's integrity check and hold no trajectory row
// whose keyframe it does not hold; over the whole run no session or job id may
// be handed out twice, every session a client was given must exist, and no
// upload may finish with data it did not bring (a tar without mav0/ must fail).
// The server process's options and restarts are in test_server_process.cc,
// replicas in test_server_replicas.cc and test_server_replica_merges.cc.
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <mutex>
#include <random>
#include <set>
#include <thread>

#include "client/api/server_client.h"
#include "core/archive/tar_writer.h"
#include "core/persistence/sqlite_db.h"
#include "tests/support/server_process.h"
#include "tests/support/server_test_fixture.h"
#include "tests/support/slam_test_clip.h"

namespace orbatlas {
namespace {

using json = nlohmann::json;
using test::ServerProcess;

// ORBATLAS_KILL_ITERATIONS overrides the count (scripts/check/stress.sh-style long runs).
int iterations() {
  const char* text = std::getenv("ORBATLAS_KILL_ITERATIONS");
  return text ? std::max(1, std::atoi(text)) : 50;
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
  for (int iteration = 0; iteration < kills; ++iteration) {
    SCOPED_TRACE("iteration " + std::to_string(iteration));
    ServerProcess server(db.path, log);
    const std::string url = server.wait_until_listening();
    ASSERT_FALSE(url.empty()) << "the server did not start after kill " << iteration << " (log: " << log << ")";
    std::atomic<bool> stop{false};
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
  const json job_list = client.get_json("/v1/jobs");
  for (const auto& j : job_list["jobs"]) {
    const std::uint64_t id = j["id"].get<std::uint64_t>();
    EXPECT_NE(j["state"], "queued");
    EXPECT_NE(j["state"], "running");
    if (handed.bad_jobs.count(id)) {
      EXPECT_EQ(j["state"], "failed") << j.dump();
    }
  }
  server.kill();
  check_file(db.path, kills);
  std::filesystem::remove(log);
}

}  // namespace
}  // namespace orbatlas
