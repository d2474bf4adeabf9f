// What an outside probe of the server found, each as a test that fails on
// the code before its fix: ids and rows after a crash, one writer per database
// and per port. Refusals before work (image headers, limits, timestamps,
// names, settings parsed in memory) are in test_server_hardening_input.cc,
// idle sessions, connections and HTTP details in
// test_server_hardening_connections.cc.
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include "client/api/server_client.h"
#include "core/archive/tar_writer.h"
#include "core/persistence/atlas_checkpoint_writer.h"
#include "core/persistence/atlas_store.h"
#include "core/persistence/database_lock.h"
#include "tests/support/server_probes.h"
#include "tests/support/server_test_fixture.h"

namespace orbatlas {
namespace {

using json = nlohmann::json;
using Clock = std::chrono::steady_clock;
using test::port_of;

TEST(ServerHardening, AFrameNeverReferencesAKeyframeTheCheckpointDidNotStore) {
  // A session whose last frame is anchored to a keyframe the atlas does not
  // have (made after the snapshot, or never): the checkpoint leaves it out
  // (before: stored, later resolved through whatever got that id).
  test::TempDbPath db("dangling");
  Atlas atlas;
  const auto map = atlas.add_map(atlas.ids().next_map_id());
  const std::vector<FrameAnchor> frames = {{100, map->id(), 7777, Pose3()}};
  SessionInfo info;
  info.id = 1;
  info.name = "dangling";
  AtlasCheckpointWriter writer(
      atlas, AtlasStore::open(db.path, "test"),
      CheckpointSession{info,
                        [&](std::size_t first) { return first < frames.size() ? frames : std::vector<FrameAnchor>{}; },
                        /*record=*/{}});
  writer.checkpoint();
  EXPECT_EQ(writer.deferred_frames(), 1u);
  EXPECT_EQ(writer.dropped_frames(), 0u);
  // It is tried again by the next checkpoints, then left out for good.
  for (int i = 1; i < AtlasCheckpointWriter::kDeferrals; ++i) writer.checkpoint();
  EXPECT_EQ(writer.deferred_frames(), static_cast<std::size_t>(AtlasCheckpointWriter::kDeferrals));
  EXPECT_EQ(writer.dropped_frames(), 1u);
  writer.checkpoint();
  EXPECT_EQ(writer.deferred_frames(), static_cast<std::size_t>(AtlasCheckpointWriter::kDeferrals));
  AtlasStore store = AtlasStore::open(db.path, "test");
  EXPECT_TRUE(store.load_trajectory(1).empty()) << "a frame referencing keyframe 7777, which is stored nowhere";
  ASSERT_EQ(store.load_sessions().size(), 1u);
}

TEST(ServerHardening, OneServerPerDatabaseAndIdsSkipWhatACrashedOneHandedOut) {
  test::TempDbPath db("lock");
  std::uint64_t keyframe_id_before = 0;
  {
    AtlasService first(test::server_options(db.path));
    keyframe_id_before = first.atlas().ids().peek(IdKind::keyframe);
    try {
      AtlasService second(test::server_options(db.path));
      FAIL() << "a second server opened the same database";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("in use by another process"), std::string::npos) << e.what();
    }
  }
  {
    // A clean stop: the ids continue where they were.
    AtlasService again(test::server_options(db.path));
    EXPECT_EQ(again.atlas().ids().peek(IdKind::keyframe), keyframe_id_before);
  }
  { DatabaseLock crashed(db.path); }  // taken and dropped without mark_stopped(): what SIGKILL leaves
  AtlasService after_crash(test::server_options(db.path));
  EXPECT_GE(after_crash.atlas().ids().peek(IdKind::keyframe), keyframe_id_before + kKeyframeIdGapAfterCrash);
  EXPECT_GE(after_crash.atlas().ids().peek(IdKind::map_point), kMapPointIdGapAfterCrash);
  EXPECT_GE(after_crash.atlas().ids().peek(IdKind::map), kMapIdGapAfterCrash);
}

TEST(ServerHardening, ASessionIsStoredWhenCreatedSoItsIdIsNeverReused) {
  test::TempDbPath db("session_rows");
  AtlasServiceOptions options = test::server_options(db.path);
  options.checkpoints.every_keyframes = 0;  // no checkpoint until shutdown
  options.checkpoints.every_seconds = 0;
  AtlasService service(options);
  SessionRequest request;
  request.name = "short";
  request.settings.config = "euroc/stereo";
  const SessionId id = service.create_session(request);
  // Before any checkpoint, the database has the row (a crash now keeps the id taken).
  AtlasStore store = AtlasStore::open(db.path, service.vocabulary().hash());
  const auto stored = store.load_session(id);
  ASSERT_TRUE(stored.has_value());
  EXPECT_EQ(stored->name, "short");
}

TEST(ServerHardening, JobIdsSurviveARestartAndNoJobReadsAnotherOnesFiles) {
  // What a kill during an upload left: a job stored as running, and its
  // extracted folder with a previous client's recording.
  test::TempDbPath db("jobs");
  {
    AtlasService service(test::server_options(db.path));
    AtlasStore store = AtlasStore::open(db.path, service.vocabulary().hash());
    // Its session: two frames stored by its last checkpoint, which saw it running.
    SessionInfo session;
    session.id = 4;
    session.name = "theirs";
    store.save_session(session);
    store.save_trajectory(4, {FrameAnchor{100, 0, 1, Pose3()}, FrameAnchor{200, 0, 1, Pose3()}});
    SessionRecord record;
    record.frames = 3;
    record.tracked = 2;
    record.keyframes = 1;
    record.mode = "map";
    record.config = "euroc/stereo";
    store.save_session_record(4, record);
    StoredJob interrupted;
    interrupted.id = 1;
    interrupted.name = "theirs";
    interrupted.state = "running";
    interrupted.frames_total = 40;
    interrupted.session = 4;
    store.save_job(interrupted);
    // Another one killed before its session's first checkpoint.
    session.id = 5;
    store.save_session(session);
    interrupted.id = 2;
    interrupted.session = 5;
    store.save_job(interrupted);
  }
  const std::filesystem::path leftover = db.path.string() + ".work/job-3/mav0/cam0";
  std::filesystem::create_directories(leftover);
  { std::ofstream(leftover.parent_path() / "data.csv") << "#timestamp [ns],filename\n"; }

  test::TestServer server(test::server_options(db.path));
  ServerClient client(server.url());
  // Before: job ids restarted at 1 and nothing said what happened to the old job.
  const json old = client.get_json("/v1/jobs/1");
  EXPECT_EQ(old["state"], "failed");
  EXPECT_NE(old.value("error", "").find("interrupted"), std::string::npos) << old.dump();
  // What was kept, as the database has it (before: "stored in session N" also of a session holding none).
  EXPECT_NE(old.value("error", "").find("session 4 keeps the 2 tracked frames its last checkpoint stored"),
            std::string::npos)
      << old.dump();
  EXPECT_NE(
      client.get_json("/v1/jobs/2").value("error", "").find("nothing of it was stored (session 5 holds no frame)"),
      std::string::npos);
  // The session reports its last checkpoint's counts and that the server stopped under it.
  const json kept = client.get_json("/v1/sessions/4");
  EXPECT_EQ(kept["state"], "stored");
  EXPECT_EQ(kept["frames"], 3);
  EXPECT_EQ(kept["tracked"], 2);
  EXPECT_EQ(kept["keyframes"], 1);
  EXPECT_EQ(kept["mode"], "map");
  EXPECT_EQ(kept["config"], "euroc/stereo");
  EXPECT_EQ(kept["ended_by"], "interrupted");
  // A session of an older database (no record): its stored frames, nothing invented.
  const json older = client.get_json("/v1/sessions/5");
  EXPECT_EQ(older["frames"], 0);
  EXPECT_FALSE(older.contains("mode"));
  EXPECT_FALSE(older.contains("ended_by"));
  EXPECT_FALSE(std::filesystem::exists(leftover)) << "the earlier run's files were kept";
  // A tar without mav0/: before, the next job "finished" with the leftover folder's frames.
  std::string tar;
  {
    TarWriter writer([&](const char* d, std::size_t n) { tar.append(d, n); });
    writer.add_directory_entry("nothing-here/");
    writer.finish();
  }
  const auto reply = client.http().Post("/v1/uploads?name=mine", tar, "application/x-tar");
  ASSERT_TRUE(reply);
  ASSERT_EQ(reply->status, 202) << reply->body;
  const std::uint64_t job = json::parse(reply->body)["job"].get<std::uint64_t>();
  EXPECT_EQ(job, 3u);
  json status;
  for (const auto deadline = Clock::now() + std::chrono::seconds(30); Clock::now() < deadline;) {
    status = client.get_json("/v1/jobs/" + std::to_string(job));
    if (status["state"] == "failed" || status["state"] == "done") break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  EXPECT_EQ(status["state"], "failed") << status.dump();
  EXPECT_NE(status.value("error", "").find("no EuRoC ASL folder"), std::string::npos) << status.dump();
  EXPECT_EQ(status.value("error", "").find(db.path.string()), std::string::npos) << "a server path in the message";
}

TEST(ServerHardening, TwoServersCannotShareAPort) {
  test::TempDbPath db_a("port_a"), db_b("port_b");
  test::TestServer first(test::server_options(db_a.path));
  AtlasService service(test::server_options(db_b.path));
  httplib::Server second;
  install_http_api(second, service, {});
  // Before: SO_REUSEPORT let the second bind succeed and split the clients.
  EXPECT_FALSE(second.bind_to_port("127.0.0.1", port_of(first.url())));
}

}  // namespace
}  // namespace orbatlas
