// Sessions in incremental checkpoints (AtlasCheckpointer): a session's
// trajectory and keyframes, its record written with its frames when it
// changed, and sessions joining and leaving a running checkpointer.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstddef>
#include <memory>
#include <mutex>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "core/persistence/atlas_checkpointer.h"
#include "core/persistence/atlas_store.h"
#include "tests/support/persistence_backends.h"
#include "tests/support/persistence_checkpoints.h"
#include "tests/persistence/test_persistence_expect.h"
#include "tests/persistence/test_persistence_random_atlas.h"

namespace orbatlas {
namespace {

using namespace test;  // NOLINT: the shared helpers of the persistence tests

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

}  // namespace
}  // namespace orbatlas
