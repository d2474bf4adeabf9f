// Incremental checkpoints (AtlasCheckpointer): only changed rows are written,
// the file always loads back equal to the atlas as of the last checkpoint, a
// failed checkpoint keeps the last good state and the next one catches up;
// what triggers a checkpoint, its thread, edits while it runs. Sessions are in
// test_persistence_checkpoint_sessions.cc, merges and several writers in
// test_persistence_checkpoint_maps.cc.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <future>
#include <mutex>
#include <random>
#include <string>
#include <thread>

#include "core/common/error.h"
#include "core/common/thread_name.h"
#include "core/common/thread_priority.h"
#include "core/persistence/atlas_checkpointer.h"
#include "core/persistence/atlas_store.h"
#include "tests/support/persistence_backends.h"
#include "tests/support/persistence_checkpoints.h"
#include "tests/persistence/test_persistence_expect.h"
#include "tests/persistence/test_persistence_random_atlas.h"

namespace orbatlas {
namespace {

using namespace test;  // NOLINT: the shared helpers of the persistence tests

// CheckpointTest (tests/support/persistence_checkpoints.h) on both backends,
// for this file and the other two of checkpoints.
ORBATLAS_PERSISTENCE_BACKENDS(CheckpointTest);
// What an SQLite file's checkpoints write to disk.
class SqliteCheckpointTest : public AtlasBackendTest {};
ORBATLAS_SQLITE_BACKEND_ONLY(SqliteCheckpointTest);

TEST_P(CheckpointTest, WritesOnlyChangedRowsAndLoadsEqual) {
  Atlas atlas;
  build_atlas(atlas, test_vocabulary(), 21);
  AtlasCheckpointer checkpointer(atlas, location(), test_vocabulary().hash(), manual_only());

  // The first checkpoint writes everything.
  ASSERT_TRUE(checkpointer.checkpoint_now());
  CheckpointStats stats = checkpointer.stats();
  EXPECT_EQ(stats.commits, 1u);
  EXPECT_EQ(stats.sequence, 1);
  EXPECT_GT(stats.last_rows.inserted, count_keyframes(atlas) + count_points(atlas));
  expect_file_holds(location(), atlas);

  // Nothing changed: nothing written, the sequence stays.
  ASSERT_TRUE(checkpointer.checkpoint_now());
  stats = checkpointer.stats();
  EXPECT_EQ(stats.checkpoints, 2u);
  EXPECT_EQ(stats.commits, 1u);
  EXPECT_EQ(stats.last_rows.total(), 0u);
  EXPECT_EQ(AtlasStore::open(location(), test_vocabulary().hash()).checkpoint_sequence(), 1);

  // One keyframe moved: exactly its row.
  const auto kf = atlas.maps()[0]->keyframes()[1];
  kf->set_T_w_b(Pose3(Eigen::Quaterniond(0.5, 0.5, -0.5, 0.5), Eigen::Vector3d(1, 2, 3)));
  ASSERT_TRUE(checkpointer.checkpoint_now());
  stats = checkpointer.stats();
  EXPECT_EQ(stats.last_rows.updated, 1u);
  EXPECT_EQ(stats.last_rows.inserted, 0u);
  EXPECT_EQ(stats.last_rows.deleted, 0u);
  EXPECT_EQ(stats.sequence, 2);
  expect_file_holds(location(), atlas);

  // One point's statistics: its row.
  atlas.maps()[1]->map_points()[3]->increase_found();
  ASSERT_TRUE(checkpointer.checkpoint_now());
  EXPECT_EQ(checkpointer.stats().last_rows.updated, 1u);
  EXPECT_EQ(checkpointer.stats().last_rows.total(), 1u);

  // Rounds of random edits: after each, the file loads equal to the atlas, and
  // an edit round writes far fewer rows than the atlas has.
  const std::size_t full_rows = checkpointer.stats().total_rows.inserted;
  std::size_t deleted = 0;
  std::mt19937_64 rng(22);
  for (int round = 0; round < 8; ++round) {
    random_edits(atlas, rng);
    ASSERT_TRUE(checkpointer.checkpoint_now()) << checkpointer.stats().last_error;
    stats = checkpointer.stats();
    EXPECT_GT(stats.last_rows.total(), 0u) << "round " << round;
    EXPECT_LT(stats.last_rows.total(), full_rows / 2) << "round " << round;
    deleted += stats.last_rows.deleted;
    expect_file_holds(location(), atlas);
    if (HasFailure()) return;
  }
  EXPECT_GT(deleted, 8u);
  EXPECT_GT(count_culled_keyframes(atlas), 4u);
  stats = checkpointer.stats();
  EXPECT_EQ(stats.failures, 0u);
  EXPECT_EQ(stats.wall_ms.count(), stats.checkpoints);
  EXPECT_EQ(stats.sequence, 11);
  checkpointer.stop();
  EXPECT_EQ(checkpointer.stats().commits, 11u);  // the final checkpoint had nothing to write
}

TEST_P(CheckpointTest, FailedCheckpointKeepsTheLastGoodStateAndRetries) {
  Atlas atlas;
  build_atlas(atlas, test_vocabulary(), 23);
  AtlasCheckpointer checkpointer(atlas, location(), test_vocabulary().hash(), manual_only());
  ASSERT_TRUE(checkpointer.checkpoint_now());

  // Another connection makes every keyframe update fail (as a full disk or an
  // I/O error would, in the middle of the transaction).
  const std::unique_ptr<SqlConnection> raw_db = raw_connection();
  SqlConnection& raw = *raw_db;
  if (backend() == SqlDialect::kSqlite) {
    raw.exec(
        "CREATE TRIGGER injected_failure BEFORE UPDATE ON keyframes "
        "BEGIN SELECT RAISE(ABORT, 'injected failure'); END");
  } else {
    raw.exec(
        "CREATE FUNCTION injected_failure() RETURNS trigger LANGUAGE plpgsql AS "
        "$$ BEGIN RAISE EXCEPTION 'injected failure'; END $$; "
        "CREATE TRIGGER injected_failure BEFORE UPDATE ON keyframes "
        "FOR EACH ROW EXECUTE FUNCTION injected_failure()");
  }
  Atlas before;
  build_atlas(before, test_vocabulary(), 23);  // the same content, as committed
  const auto kfs = atlas.maps()[0]->keyframes();
  std::mt19937_64 rng(1);
  kfs[0]->set_T_w_b(random_pose(rng));
  add_random_point(*atlas.maps()[0], rng);
  EXPECT_FALSE(checkpointer.checkpoint_now());
  CheckpointStats stats = checkpointer.stats();
  EXPECT_EQ(stats.failures, 1u);
  EXPECT_NE(stats.last_error.find("injected failure"), std::string::npos) << stats.last_error;
  EXPECT_EQ(stats.commits, 1u);
  EXPECT_EQ(raw.query_int64("SELECT checkpoint_seq FROM atlas"), 1);
  expect_file_holds(location(), before);  // all or nothing: the new point is not there either

  // The cause goes away; the next checkpoint writes everything changed since the last commit.
  raw.exec(backend() == SqlDialect::kSqlite ? "DROP TRIGGER injected_failure"
                                            : "DROP TRIGGER injected_failure ON keyframes");
  kfs[1]->set_T_w_b(random_pose(rng));
  ASSERT_TRUE(checkpointer.checkpoint_now());
  stats = checkpointer.stats();
  EXPECT_EQ(stats.last_rows.updated, 3u);  // two keyframes, the atlas row (allocator)
  EXPECT_EQ(stats.last_rows.inserted, 1u);
  EXPECT_EQ(stats.sequence, 2);
  expect_file_holds(location(), atlas);
}

TEST_P(CheckpointTest, KeyframeCountAndTimerTriggerCheckpoints) {
  Atlas atlas;
  const auto map = atlas.create_map();
  std::mt19937_64 rng(26);

  // Every 3 keyframes, no timer: two notifications do nothing, the third wakes the worker.
  std::promise<void> started;
  std::once_flag once;
  CheckpointOptions options;
  options.every_keyframes = 3;
  options.every_seconds = 0;
  options.before_transaction = [&] { std::call_once(once, [&] { started.set_value(); }); };
  {
    AtlasCheckpointer checkpointer(atlas, location(), test_vocabulary().hash(), options);
    auto future = started.get_future();
    for (int i = 0; i < 2; ++i) {
      add_random_keyframe(*map, rng, nullptr, 10, true);
      checkpointer.notify_keyframe();
    }
    EXPECT_EQ(future.wait_for(std::chrono::milliseconds(300)), std::future_status::timeout);
    add_random_keyframe(*map, rng, nullptr, 10, true);
    checkpointer.notify_keyframe();
    EXPECT_EQ(future.wait_for(std::chrono::seconds(10)), std::future_status::ready);
  }

  // A timer alone.
  std::promise<void> timed;
  std::once_flag timed_once;
  options.every_keyframes = 0;
  options.every_seconds = 0.05;
  options.before_transaction = [&] { std::call_once(timed_once, [&] { timed.set_value(); }); };
  AtlasCheckpointer checkpointer(atlas, location(), test_vocabulary().hash(), options);
  EXPECT_EQ(timed.get_future().wait_for(std::chrono::seconds(10)), std::future_status::ready);

  // stop(): a final checkpoint, idempotent; nothing afterwards.
  add_random_keyframe(*map, rng, nullptr, 10, true);
  checkpointer.stop();
  checkpointer.stop();
  EXPECT_FALSE(checkpointer.checkpoint_now());
  EXPECT_EQ(checkpointer.stats().failures, 0u);
  Atlas loaded;
  AtlasStore::open(location(), test_vocabulary().hash()).load_atlas(loaded, nullptr);
  EXPECT_EQ(count_keyframes(loaded), 4u);
}

// Bytes this process has handed to write() and pwrite() so far (Linux).
std::uint64_t written_by_this_process() {
  std::ifstream io("/proc/self/io");
  std::string key;
  std::uint64_t value = 0;
  while (io >> key >> value)
    if (key == "wchar:") return value;
  return 0;
}

// A checkpoint that moves every point and deletes keyframes (their
// observations cascade) writes what changed, not a page per statement:
// SQLite's statement journals stay in memory (atlas_store.cc). Measured 161 kB
// for a 651-kB database and log; with the journals in a temporary file, 4257 kB.
// Four live sessions' checkpoints then wrote 4 GB in a minute for a 25-MB
// database (CHANGELOG.md, 2026-11-28).
TEST_P(SqliteCheckpointTest, ACheckpointWritesWhatChangedOnly) {
  Atlas atlas;
  build_atlas(atlas, test_vocabulary(), 31);
  AtlasCheckpointer checkpointer(atlas, location(), test_vocabulary().hash(), manual_only());
  ASSERT_TRUE(checkpointer.checkpoint_now());
  std::mt19937_64 rng(32);
  for (const auto& map : atlas.maps())
    for (const auto& mp : map->map_points()) mp->set_p_w(mp->p_w() + Eigen::Vector3d(0.01, 0.0, 0.0));
  random_edits(atlas, rng);
  const std::uint64_t before = written_by_this_process();
  ASSERT_TRUE(checkpointer.checkpoint_now());
  const double written = static_cast<double>(written_by_this_process() - before);
  std::error_code no_wal;
  const auto wal = std::filesystem::file_size(location() + "-wal", no_wal);
  const double file = static_cast<double>(std::filesystem::file_size(location()) + (no_wal ? 0 : wal));
  ASSERT_GT(checkpointer.stats().last_rows.updated, count_points(atlas) / 2);
  EXPECT_LT(written, 0.5 * file) << "bytes written; the database and its log are " << file << " bytes";
}

// A map server's checkpoints run at its background threads' nice value, so
// that writing the database leaves the cores to tracking first.
TEST_P(CheckpointTest, TheCheckpointThreadRunsAtItsNiceValue) {
  Atlas atlas;
  const auto map = atlas.create_map();
  std::mt19937_64 rng(27);
  add_random_keyframe(*map, rng, nullptr, 10, true);
  std::atomic<int> seen{-1};
  CheckpointOptions options;
  options.every_keyframes = 0;
  options.every_seconds = 0;
  options.worker_nice = 7;
  std::string name;
  options.before_transaction = [&] {
    seen.store(current_thread_nice());
    name = current_thread_name();
  };
  const int own = current_thread_nice();
  AtlasCheckpointer checkpointer(atlas, location(), test_vocabulary().hash(), options);
  EXPECT_TRUE(checkpointer.checkpoint_now());
  EXPECT_EQ(seen.load(), 7);
  EXPECT_EQ(name, "checkpoints");
  EXPECT_EQ(current_thread_nice(), own);  // the caller's thread is left as it was

  options.worker_nice = 20;
  EXPECT_THROW(AtlasCheckpointer(atlas, location(), test_vocabulary().hash(), options), Error);
}

// Checkpoints while another thread edits the atlas: every checkpoint commits
// (a snapshot consistent per object satisfies every constraint), and once the
// edits stop, the file equals the atlas.
TEST_P(CheckpointTest, ConcurrentEditsNeverBreakACheckpoint) {
  Atlas atlas;
  build_atlas(atlas, test_vocabulary(), 27);
  CheckpointOptions options;
  options.every_keyframes = 2;
  options.every_seconds = 0.01;
  AtlasCheckpointer checkpointer(atlas, location(), test_vocabulary().hash(), options);
  std::thread editor([&] {
    std::mt19937_64 rng(28);
    for (int round = 0; round < 60; ++round) {
      random_edits(atlas, rng);
      checkpointer.notify_keyframe();
      checkpointer.notify_keyframe();
      std::this_thread::sleep_for(std::chrono::milliseconds(5));  // frames come at a rate
    }
  });
  editor.join();
  ASSERT_TRUE(checkpointer.checkpoint_now());
  const CheckpointStats stats = checkpointer.stats();
  EXPECT_EQ(stats.failures, 0u) << stats.last_error;
  EXPECT_GT(stats.commits, 3u);
  expect_file_holds(location(), atlas);
}

}  // namespace
}  // namespace orbatlas
