// Incremental checkpoints (AtlasCheckpointer): only changed rows are written,
// the file always loads back equal to the atlas as of the last checkpoint, a
// failed checkpoint keeps the last good state and the next one catches up.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <future>
#include <mutex>
#include <random>
#include <set>
#include <thread>
#include <unordered_set>

#include "core/common/error.h"
#include "core/common/thread_name.h"
#include "core/common/thread_priority.h"
#include "core/persistence/atlas_checkpointer.h"
#include "core/persistence/atlas_store.h"
#include "tests/support/persistence_backends.h"
#include "tests/persistence/test_persistence_expect.h"
#include "tests/persistence/test_persistence_random_atlas.h"

namespace orbatlas {
namespace {

using namespace test;  // NOLINT: the shared helpers of the persistence tests

CheckpointOptions manual_only() {
  CheckpointOptions options;
  options.every_keyframes = 0;
  options.every_seconds = 0;
  return options;
}

// Loads the file through a connection of its own and compares every field.
void expect_file_holds(const std::filesystem::path& path, const Atlas& atlas) {
  AtlasStore store = AtlasStore::open(path, test_vocabulary().hash());
  Atlas loaded;
  store.load_atlas(loaded, &test_vocabulary());
  expect_atlas_eq(atlas, loaded, true);
}

template <class T>
const std::shared_ptr<T>& pick(const std::vector<std::shared_ptr<T>>& v, std::mt19937_64& rng) {
  return v[rng() % v.size()];
}

// One round of the edits local mapping and loop closing make: new keyframes and
// points, new observations and a replaced / erased slot, new covisibility,
// parents and a loop edge, moved keyframes and points, statistics, culled
// keyframes (with children and parents: chains of anchors) and points, and now
// and then a new map that becomes the active one.
void random_edits(Atlas& atlas, std::mt19937_64& rng) {
  if (rng() % 4 == 0) atlas.create_map();
  const auto map = atlas.active_map();
  std::vector<std::shared_ptr<KeyFrame>> fresh;
  for (int i = 0; i < 2; ++i) fresh.push_back(add_random_keyframe(*map, rng, &test_vocabulary(), 60, i == 0));
  auto keyframes = map->keyframes();
  std::vector<std::shared_ptr<MapPoint>> points;
  for (int i = 0; i < 30; ++i) points.push_back(add_random_point(*map, rng));
  observe_randomly(keyframes, points, rng, 2, 4);
  for (const auto& kf : fresh) {
    kf->update_connections(5);
    if (keyframes.size() > fresh.size()) kf->set_parent(keyframes[rng() % (keyframes.size() - fresh.size())]);
  }
  pick(keyframes, rng)->update_connections(5);
  if (keyframes.size() > 3) {
    const auto& a = pick(keyframes, rng);
    const auto& b = pick(keyframes, rng);
    if (a != b) a->add_loop_edge(b);
  }
  // An observation moves to another point, one goes.
  const auto& edited = pick(keyframes, rng);
  for (std::size_t slot = 0; slot < edited->slot_count(); ++slot) {
    if (!edited->map_point(slot)) continue;
    if (rng() % 2) {
      edited->erase_slot(slot);
    } else {
      edited->replace(slot, add_random_point(*map, rng));
    }
    break;
  }
  pick(keyframes, rng)->set_T_w_b(random_pose(rng));
  const auto all_points = map->map_points();
  for (int i = 0; i < 5; ++i) {
    const auto& mp = pick(all_points, rng);
    mp->set_p_w(mp->p_w() + Eigen::Vector3d(0.01, 0, 0));
    mp->increase_visible();
  }
  for (int i = 0; i < 3; ++i) map->cull_map_point(pick(all_points, rng)->id());
  if (keyframes.size() > 4) map->cull_keyframe(pick(keyframes, rng)->id());
}

// Every test runs on SQLite and on PostgreSQL (AtlasCheckpointer opening a
// file or a postgresql:// URI).
class CheckpointTest : public AtlasBackendTest {};
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

TEST_P(CheckpointTest, SessionTrajectoryAndKeyframeSessions) {
  Atlas atlas;
  build_atlas(atlas, test_vocabulary(), 24);
  const std::size_t old_keyframes = count_keyframes(atlas);
  std::mutex frames_mutex;  // the trajectory source is called on the checkpoint thread
  std::vector<FrameAnchor> frames;
  std::vector<std::size_t> asked;  // what the checkpoints asked the source for
  CheckpointSession session;
  session.info.id = 5;
  session.info.name = "live";
  session.trajectory = [&](std::size_t first) {
    std::lock_guard lock(frames_mutex);
    asked.push_back(first);
    return std::vector<FrameAnchor>(frames.begin() + static_cast<std::ptrdiff_t>(std::min(first, frames.size())),
                                    frames.end());
  };
  AtlasCheckpointer checkpointer(atlas, location(), test_vocabulary().hash(), manual_only(), session);
  std::mt19937_64 rng(25);
  const auto map = atlas.active_map();
  const auto add_frames = [&](int n) {
    std::lock_guard lock(frames_mutex);
    for (int i = 0; i < n; ++i)
      frames.push_back({static_cast<TimestampNs>(frames.size()) * 50'000'000, map->id(), map->keyframes().front()->id(),
                        random_pose(rng)});
  };
  add_frames(20);
  ASSERT_TRUE(checkpointer.checkpoint_now());
  // New keyframes are the session's; 5 frames more, and only they are asked for.
  const auto kf1 = add_random_keyframe(*map, rng, &test_vocabulary(), 40, true);
  const auto kf2 = add_random_keyframe(*map, rng, &test_vocabulary(), 40, true);
  add_frames(5);
  ASSERT_TRUE(checkpointer.checkpoint_now());
  const CheckpointStats stats = checkpointer.stats();
  EXPECT_EQ(stats.last_rows.inserted, 2u + 5u);  // two keyframes, five frames
  EXPECT_EQ(stats.last_rows.updated, 1u);        // the atlas row (allocator)
  {
    std::lock_guard lock(frames_mutex);
    EXPECT_EQ(asked, (std::vector<std::size_t>{0, 20}));
  }
  checkpointer.stop();

  AtlasStore store = AtlasStore::open(location(), test_vocabulary().hash());
  const auto stored_session = store.load_session(5);
  ASSERT_TRUE(stored_session.has_value());
  EXPECT_EQ(stored_session->name, "live");
  const auto stored_frames = store.load_trajectory(5);
  ASSERT_EQ(stored_frames.size(), frames.size());
  for (std::size_t i = 0; i < frames.size(); ++i) {
    EXPECT_EQ(stored_frames[i].t_ns, frames[i].t_ns);
    expect_pose_eq(stored_frames[i].T_ref_b, frames[i].T_ref_b, "frame " + std::to_string(i));
  }
  Atlas loaded;
  const AtlasLoadReport report = store.load_atlas(loaded, &test_vocabulary());
  EXPECT_EQ(count_keyframes(loaded), old_keyframes + 2);
  ASSERT_EQ(report.keyframe_sessions.size(), 2u);  // keyframes made before the checkpointer have none
  EXPECT_EQ(report.keyframe_sessions.at(kf1->id()), 5u);
  EXPECT_EQ(report.keyframe_sessions.at(kf2->id()), 5u);

  // Two frames at one time: the checkpoint fails (and says why), nothing else happens.
  Atlas empty;
  CheckpointSession twice;
  twice.info.id = 6;
  twice.trajectory = [](std::size_t) {
    return std::vector<FrameAnchor>{FrameAnchor{7, 0, 0, Pose3()}, FrameAnchor{7, 0, 1, Pose3()}};
  };
  AtlasCheckpointer failing(empty, location(), test_vocabulary().hash(), manual_only(), twice);
  EXPECT_FALSE(failing.checkpoint_now());
  EXPECT_NE(failing.stats().last_error.find("two frames at timestamp 7"), std::string::npos)
      << failing.stats().last_error;
}

// A session's record (its counts, how it ended) goes into the checkpoint that
// writes its frames, and again only when it changed.
TEST_P(CheckpointTest, ASessionsRecordIsWrittenWithItsFramesWhenItChanges) {
  Atlas atlas;
  build_atlas(atlas, test_vocabulary(), 12);
  std::mutex mutex;  // both sources are called on the checkpoint thread
  std::vector<FrameAnchor> frames;
  SessionRecord record;
  record.mode = "map";
  record.config = "euroc/stereo";
  CheckpointSession session;
  session.info.id = 8;
  session.info.name = "recorded";
  session.trajectory = [&](std::size_t first) {
    std::lock_guard lock(mutex);
    return std::vector<FrameAnchor>(frames.begin() + static_cast<std::ptrdiff_t>(std::min(first, frames.size())),
                                    frames.end());
  };
  session.record = [&] {
    std::lock_guard lock(mutex);
    return record;
  };
  AtlasCheckpointer checkpointer(atlas, location(), test_vocabulary().hash(), manual_only(), session);
  const auto map = atlas.active_map();
  const auto track = [&](int n, int rejected) {
    std::lock_guard lock(mutex);
    for (int i = 0; i < n; ++i)
      frames.push_back({static_cast<TimestampNs>(frames.size() + 1) * 50'000'000, map->id(),
                        map->keyframes().front()->id(), Pose3()});
    record.frames += static_cast<std::size_t>(n + 1);  // one frame not tracked
    record.tracked += static_cast<std::size_t>(n);
    record.keyframes += 1;
    record.rejected_frames += static_cast<std::size_t>(rejected);
    record.imu_samples += 10u * static_cast<std::size_t>(n);
  };
  const auto stored = [&] {
    AtlasStore store = AtlasStore::open(location(), test_vocabulary().hash());
    return store.load_session_records();
  };
  track(10, 1);
  ASSERT_TRUE(checkpointer.checkpoint_now());
  ASSERT_EQ(stored().size(), 1u);
  EXPECT_EQ(stored().at(8), record);
  // Nothing new: the next checkpoint writes nothing, the record included.
  const std::uint64_t commits = checkpointer.stats().commits;
  ASSERT_TRUE(checkpointer.checkpoint_now());
  EXPECT_EQ(checkpointer.stats().commits, commits);
  // A count alone changes: written, one row updated.
  {
    std::lock_guard lock(mutex);
    ++record.skipped_frames;
  }
  ASSERT_TRUE(checkpointer.checkpoint_now());
  EXPECT_EQ(checkpointer.stats().commits, commits + 1);
  EXPECT_EQ(checkpointer.stats().last_rows.total(), 1u) << "the record alone";
  EXPECT_EQ(stored().at(8), record);
  // It fails: the end is stored by the checkpoint after end_session, with its last frames.
  track(3, 0);
  {
    std::lock_guard lock(mutex);
    record.outcome = "failed";
    record.error = "tracking: out of memory";
  }
  checkpointer.end_session(8);
  ASSERT_TRUE(checkpointer.checkpoint_now());
  EXPECT_EQ(stored().at(8), record);
  AtlasStore store = AtlasStore::open(location(), test_vocabulary().hash());
  EXPECT_EQ(store.load_trajectory(8).size(), 13u);
  // Ended: the writer no longer asks for it; the stored record stays as it was.
  {
    std::lock_guard lock(mutex);
    record.frames = 0;
  }
  ASSERT_TRUE(checkpointer.checkpoint_now());
  EXPECT_EQ(stored().at(8).frames, 15u);
}

// The server's case: sessions join and leave a running checkpointer, their
// keyframes interleave, each keeps its own trajectory.
TEST_P(CheckpointTest, SessionsJoinAndLeaveWithInterleavedKeyframes) {
  Atlas atlas;
  build_atlas(atlas, test_vocabulary(), 12);
  AtlasCheckpointer checkpointer(atlas, location(), test_vocabulary().hash(), manual_only());
  ASSERT_TRUE(checkpointer.checkpoint_now());  // the atlas alone, no session
  std::mt19937_64 rng(31);
  const auto map = atlas.active_map();
  const KeyframeId anchor_kf = map->keyframes().front()->id();
  const auto frames_of = [&](TimestampNs offset, int n) {
    auto frames = std::make_shared<std::vector<FrameAnchor>>();
    for (int i = 0; i < n; ++i) frames->push_back({offset + i * 50'000'000LL, map->id(), anchor_kf, random_pose(rng)});
    return frames;
  };
  const auto a_frames = frames_of(0, 7), b_frames = frames_of(1'000'000, 4);
  for (const auto& [id, frames] : {std::pair{SessionId{11}, a_frames}, std::pair{SessionId{12}, b_frames}}) {
    CheckpointSession s;
    s.info.id = id;
    s.info.name = "client " + std::to_string(id);
    s.trajectory = [frames](std::size_t first) {  // owns what it reads
      return std::vector<FrameAnchor>(frames->begin() + static_cast<std::ptrdiff_t>(std::min(first, frames->size())),
                                      frames->end());
    };
    checkpointer.add_session(std::move(s));
  }
  std::vector<std::pair<KeyframeId, SessionId>> made;
  for (int i = 0; i < 6; ++i) {
    const SessionId by = i % 2 == 0 ? 11 : 12;
    const auto kf = add_random_keyframe(*map, rng, &test_vocabulary(), 30, true);
    checkpointer.notify_keyframe(by, kf->id());
    made.emplace_back(kf->id(), by);
  }
  ASSERT_TRUE(checkpointer.checkpoint_now());
  EXPECT_EQ(checkpointer.stats().last_rows.inserted, 2u + 6u + 7u + 4u);  // sessions, keyframes, frames
  // Session 12 ends: its last frames are written once more, then it is forgotten.
  b_frames->push_back({9'000'000'000LL, map->id(), anchor_kf, random_pose(rng)});
  checkpointer.end_session(12);
  ASSERT_TRUE(checkpointer.checkpoint_now());
  EXPECT_EQ(checkpointer.stats().last_rows.inserted, 1u);
  b_frames->push_back({9'500'000'000LL, map->id(), anchor_kf, random_pose(rng)});  // after the end: not stored
  ASSERT_TRUE(checkpointer.checkpoint_now());
  EXPECT_EQ(checkpointer.stats().last_rows.total(), 0u);
  checkpointer.stop();

  AtlasStore store = AtlasStore::open(location(), test_vocabulary().hash());
  ASSERT_EQ(store.load_sessions().size(), 2u);
  EXPECT_EQ(store.load_session(12)->name, "client 12");
  EXPECT_EQ(store.load_trajectory(11).size(), 7u);
  EXPECT_EQ(store.load_trajectory(12).size(), 5u);
  Atlas loaded;
  const AtlasLoadReport report = store.load_atlas(loaded, &test_vocabulary());
  expect_atlas_eq(atlas, loaded, true);
  for (const auto& [kf, session] : made) EXPECT_EQ(report.keyframe_sessions.at(kf), session) << "keyframe " << kf;
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
  EXPECT_LT(written, 0.5 * file) << "database and its log " << file << " bytes";
  std::printf("a checkpoint moving every point wrote %.0f kB; the database and its log are %.0f kB\n", written / 1e3,
              file / 1e3);
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

// A merge (Map::absorb + Atlas::remove_map): the source map's objects move into
// the target with their poses transformed; an incremental checkpoint moves
// their rows and deletes the source map, a full save of a merged atlas deletes
// the stored rows of the map it no longer has; both load equal.
TEST_P(CheckpointTest, MergedMapMovesItsRowsAndLeavesTheFile) {
  Atlas atlas;
  build_atlas(atlas, test_vocabulary(), 33);
  AtlasCheckpointer checkpointer(atlas, location(), test_vocabulary().hash(), manual_only());
  ASSERT_TRUE(checkpointer.checkpoint_now());

  const auto maps = atlas.maps();
  ASSERT_GE(maps.size(), 2u);
  const auto target = maps[0], source = maps[1];
  ASSERT_GT(source->keyframe_count(), 0u);
  const MapId source_id = source->id();
  const std::size_t target_kfs = target->keyframe_count(), source_kfs = source->keyframe_count();
  const std::size_t target_points = target->map_point_count(), source_points = source->map_point_count();
  const auto culled_before = source->culled_keyframes();
  const Pose3 T(Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(0.2, -0.3, 0.9).normalized())),
                Eigen::Vector3d(4.0, -2.0, 0.5));
  const auto kf = source->keyframes().front();
  const auto mp = source->map_points().front();
  const Pose3 kf_before = kf->T_w_b();
  const Eigen::Vector3d p_before = mp->p_w(), n_before = mp->normal();

  {
    const auto whole = atlas.lock_maps_exclusive();
    const Map::AbsorbCounts moved = target->absorb(*source, T);
    EXPECT_EQ(moved.keyframes, source_kfs);
    EXPECT_EQ(moved.map_points, source_points);
    EXPECT_EQ(moved.culled_keyframes, culled_before.size());
    EXPECT_NE(atlas.remove_map(source_id), nullptr);
  }
  EXPECT_EQ(atlas.map(source_id), nullptr);
  EXPECT_EQ(target->keyframe_count(), target_kfs + source_kfs);
  EXPECT_EQ(target->map_point_count(), target_points + source_points);
  EXPECT_EQ(source->keyframe_count(), 0u);
  EXPECT_EQ(kf->map_id(), target->id());
  EXPECT_EQ(mp->map_id(), target->id());
  EXPECT_LT(translation_distance(kf->T_w_b(), T * kf_before), 1e-12);
  EXPECT_LT(rotation_distance(kf->T_w_b(), T * kf_before), 1e-12);
  EXPECT_LT((mp->p_w() - T * p_before).norm(), 1e-12);
  EXPECT_LT((mp->normal() - T.q * n_before).norm(), 1e-12);
  // A frame anchored to a moved keyframe resolves in the target map now.
  const auto located = atlas.locate_frame(FrameAnchor{0, source_id, kf->id(), Pose3()});
  ASSERT_TRUE(located.has_value());
  EXPECT_EQ(located->first, target->id());
  EXPECT_EQ(atlas.map_holding(kf->id()), target->id());
  for (const auto& c : culled_before) {
    const auto pose = target->keyframe_pose(c.id);
    ASSERT_TRUE(pose.has_value()) << "culled keyframe " << c.id;
  }

  ASSERT_TRUE(checkpointer.checkpoint_now());
  expect_file_holds(location(), atlas);
  EXPECT_EQ(AtlasStore::open(location(), test_vocabulary().hash()).stored_map_ids().size(), atlas.maps().size());

  // A full save of the merged atlas into a file that still has both maps.
  const std::string other = another_location("merge_full");
  {
    Atlas before;
    build_atlas(before, test_vocabulary(), 33);
    AtlasStore::open(other, test_vocabulary().hash()).save_atlas(before);
  }
  AtlasStore store = AtlasStore::open(other, test_vocabulary().hash());
  store.save_atlas(atlas);
  EXPECT_EQ(store.stored_map_ids().size(), atlas.maps().size());
  expect_file_holds(other, atlas);
}

// Several writers of one database (replicas): each writes only the
// maps it may write (its ids from a range of its own), and neither writes nor
// deletes the others' rows; a map it may write again after a time it could not
// is rewritten whole, so the file then holds its version exactly.
TEST_P(CheckpointTest, TwoWritersEachWriteOnlyTheirOwnMaps) {
  Atlas a, b;
  build_atlas(a, test_vocabulary(), 41);
  // b's ids come from ranges a never uses.
  b.ids().confine(IdKind::map, 1000, 2000);
  b.ids().confine(IdKind::keyframe, std::uint64_t{1} << 32, std::uint64_t{2} << 32);
  b.ids().confine(IdKind::map_point, std::uint64_t{1} << 40, std::uint64_t{2} << 40);
  build_atlas(b, test_vocabulary(), 42);
  ASSERT_GE(a.maps().size(), 2u);
  const MapId a_own = a.maps()[0]->id(), a_other = a.maps()[1]->id();  // a may not write a_other
  const std::size_t a_maps_at_start = a.maps().size();
  std::mutex ownership_mutex;
  std::set<MapId> a_writes = {a_own};
  std::vector<std::vector<MapId>> a_candidates;
  CheckpointOptions a_options = manual_only();
  a_options.writable_maps = [&](SqlConnection&, const std::vector<MapId>& candidates,
                                const std::unordered_set<MapId>&) {
    std::lock_guard lock(ownership_mutex);
    a_candidates.push_back(candidates);
    std::unordered_set<MapId> out;
    for (const MapId m : candidates)
      if (a_writes.count(m)) out.insert(m);
    return out;
  };
  AtlasCheckpointer ca(a, location(), test_vocabulary().hash(), a_options);
  AtlasCheckpointer cb(b, location(), test_vocabulary().hash(), manual_only());  // every map of its own

  // The file holds a's own map and every map of b, each as its writer has it.
  const auto expect_file = [&](const std::vector<std::pair<const Atlas*, MapId>>& expected) {
    Atlas loaded;
    AtlasStore::open(location(), test_vocabulary().hash()).load_atlas(loaded, &test_vocabulary());
    std::string ids;
    for (const auto& m : loaded.maps()) ids += std::to_string(m->id()) + " ";
    ids += "| expected ";
    for (const auto& [atlas, id] : expected) ids += std::to_string(id) + " ";
    ASSERT_EQ(loaded.maps().size(), expected.size()) << ids;
    for (const auto& [atlas, id] : expected) {
      ASSERT_NE(loaded.map(id), nullptr) << "map " << id;
      expect_map_eq(*atlas->map(id), *loaded.map(id), true);
    }
  };
  std::vector<std::pair<const Atlas*, MapId>> expected = {{&a, a_own}};
  for (const auto& m : b.maps()) expected.push_back({&b, m->id()});
  std::mt19937_64 rng(43);
  for (int round = 0; round < 4; ++round) {
    ASSERT_TRUE(ca.checkpoint_now()) << ca.stats().last_error;
    ASSERT_TRUE(cb.checkpoint_now()) << cb.stats().last_error;
    expect_file(expected);
    if (HasFailure()) return;
    // Edits in every map of both (a's map it may not write included).
    for (Atlas* atlas : {&a, &b}) {
      for (const auto& m : atlas->maps()) {
        atlas->set_active(m->id());
        random_edits(*atlas, rng);
      }
    }
    // random_edits may make new maps: a writes none of them, b all of its own.
    expected.assign({{&a, a_own}});
    for (const auto& m : b.maps()) expected.push_back({&b, m->id()});
  }
  EXPECT_FALSE(a_candidates.empty());
  EXPECT_EQ(a_candidates.front().size(), a_maps_at_start);  // asked about every map it had

  ASSERT_TRUE(cb.checkpoint_now()) << cb.stats().last_error;  // b's last edits
  // a may write a_other now (it took it over): rewritten whole, as a has it.
  {
    std::lock_guard lock(ownership_mutex);
    a_writes.insert(a_other);
  }
  ASSERT_TRUE(ca.checkpoint_now()) << ca.stats().last_error;
  expected.push_back({&a, a_other});
  expect_file(expected);
  // ... and an edit of it afterwards is an ordinary incremental write.
  a.map(a_other)->map_points()[0]->increase_found();
  ASSERT_TRUE(ca.checkpoint_now());
  EXPECT_EQ(ca.stats().last_rows.total(), 1u);
  // a may no longer write a_own (another writer took it): a's edits stay out of the file.
  {
    std::lock_guard lock(ownership_mutex);
    a_writes.erase(a_own);
  }
  const auto kept = ca.stats().commits;
  a.map(a_own)->map_points()[0]->increase_found();
  ASSERT_TRUE(ca.checkpoint_now());
  EXPECT_EQ(ca.stats().commits, kept);  // nothing of it written
  EXPECT_EQ(ca.stats().failures, 0u);
  EXPECT_EQ(cb.stats().failures, 0u);
}

// Replicas watch the maps others change: a checkpoint says, inside its
// transaction, which maps' rows it changed (and only those).
TEST_P(CheckpointTest, ACheckpointSaysWhichMapsItChanged) {
  Atlas atlas;
  build_atlas(atlas, test_vocabulary(), 51);
  const auto maps = atlas.maps();
  ASSERT_GE(maps.size(), 2u);
  std::mutex mutex;
  std::vector<std::vector<MapId>> told;
  CheckpointOptions options = manual_only();
  options.maps_changed = [&](SqlConnection&, const std::vector<MapId>& changed) {
    std::lock_guard lock(mutex);
    told.push_back(changed);
  };
  AtlasCheckpointer checkpointer(atlas, location(), test_vocabulary().hash(), options);
  const auto last = [&] {
    std::lock_guard lock(mutex);
    return told.empty() ? std::vector<MapId>{} : told.back();
  };
  ASSERT_TRUE(checkpointer.checkpoint_now());
  std::vector<MapId> all;
  for (const auto& m : maps) all.push_back(m->id());
  EXPECT_EQ(last(), all);  // the first checkpoint writes every map
  ASSERT_TRUE(checkpointer.checkpoint_now());
  EXPECT_EQ(told.size(), 1u);  // nothing changed: not told
  maps[1]->map_points()[2]->increase_found();
  ASSERT_TRUE(checkpointer.checkpoint_now());
  EXPECT_EQ(last(), std::vector<MapId>{maps[1]->id()});
  maps[0]->keyframes()[1]->set_T_w_b(Pose3(Eigen::Quaterniond(0.5, 0.5, -0.5, 0.5), Eigen::Vector3d(1, 2, 3)));
  const auto kf = maps[1]->keyframes()[0];
  for (std::size_t slot = 0; slot < kf->slot_count(); ++slot)
    if (kf->map_point(slot)) {
      kf->erase_slot(slot);  // an observation
      break;
    }
  ASSERT_TRUE(checkpointer.checkpoint_now());
  EXPECT_EQ(last(), (std::vector<MapId>{maps[0]->id(), maps[1]->id()}));
  EXPECT_EQ(told.size(), 3u);
}

// A merge that lands between a checkpoint's snapshot and its transaction (found
// by ThreadSanitizer's slow runs: the writer read the removed maps after the
// snapshot, and the next checkpoint then inserted rows the file had): that
// checkpoint writes the maps as its snapshot had them, the next one the merge.
TEST_P(CheckpointTest, AMergeBetweenTheSnapshotAndTheTransactionIsWrittenByTheNext) {
  Atlas atlas;
  build_atlas(atlas, test_vocabulary(), 61);
  const auto maps = atlas.maps();
  ASSERT_GE(maps.size(), 2u);
  const auto target = maps[0], source = maps[1];
  bool merge_now = false;
  CheckpointOptions options = manual_only();
  options.before_transaction = [&] {
    if (!merge_now) return;
    merge_now = false;
    const auto whole = atlas.lock_maps_exclusive();
    target->absorb(*source, Pose3());
    atlas.remove_map(source->id());
  };
  AtlasCheckpointer checkpointer(atlas, location(), test_vocabulary().hash(), options);
  ASSERT_TRUE(checkpointer.checkpoint_now());  // both maps written
  source->map_points()[0]->increase_found();   // something to write
  merge_now = true;
  ASSERT_TRUE(checkpointer.checkpoint_now()) << checkpointer.stats().last_error;
  ASSERT_EQ(atlas.map(source->id()), nullptr);
  ASSERT_TRUE(checkpointer.checkpoint_now()) << checkpointer.stats().last_error;
  expect_file_holds(location(), atlas);
  EXPECT_EQ(checkpointer.stats().failures, 0u);
}

}  // namespace
}  // namespace orbatlas
