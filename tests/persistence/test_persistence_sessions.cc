// What the atlas stores besides its maps, round trips on SQLite and on
// PostgreSQL: sessions with their cameras, session records, upload jobs and
// trajectories, and the values the schema refuses (the stored rows unchanged).
#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <string>
#include <vector>

#include "core/common/error.h"
#include "core/persistence/atlas_store.h"
#include "tests/support/persistence_backends.h"
#include "tests/persistence/test_persistence_expect.h"
#include "tests/persistence/test_persistence_random_atlas.h"
#include "tests/support/persistence_sessions.h"

namespace orbatlas {
namespace {

using namespace test;  // NOLINT: the shared helpers of the persistence tests

// Instantiated on both backends in test_persistence.cc.
using PersistenceBackends = AtlasBackendTest;

TEST_P(PersistenceBackends, SessionsRoundTrip) {
  AtlasStore store = open_store(test_vocabulary().hash());
  SessionInfo stereo;
  stereo.id = 3;
  stereo.name = "MH_01_easy stereo";
  stereo.sensor = SensorType::kStereo;
  stereo.created_ns = 1'700'000'000'123'456'789LL;
  stereo.cameras = {camera(CameraModel::kPinholeRadTan, {-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05}, 0),
                    camera(CameraModel::kPinholeRadTan, {-0.28368365, 0.07451284, -0.00010473, -3.5552e-05, 1e-7}, 1)};
  SessionInfo fisheye;
  fisheye.id = 1;
  fisheye.name = "fisheye rig, inertial";
  fisheye.sensor = SensorType::kMonocularInertial;
  fisheye.created_ns = 42;
  fisheye.cameras = {camera(CameraModel::kKannalaBrandt, {0.0034, 0.0007, -0.0020, 0.0002}, 2)};
  SessionInfo bare;  // no camera at all
  bare.id = 9;
  bare.name = "";
  store.save_session(stereo);
  store.save_session(fisheye);
  store.save_session(bare);

  const std::vector<SessionInfo> all = store.load_sessions();
  ASSERT_EQ(all.size(), 3u);
  expect_session_eq(all[0], fisheye);
  expect_session_eq(all[1], stereo);
  expect_session_eq(all[2], bare);
  const auto one = store.load_session(3);
  ASSERT_TRUE(one.has_value());
  expect_session_eq(*one, stereo);
  EXPECT_FALSE(store.load_session(4).has_value());

  // Replacing a session (fewer cameras, new name) keeps its trajectory.
  store.save_trajectory(3, {FrameAnchor{100, 0, 1, Pose3()}});
  stereo.name = "renamed";
  stereo.cameras.pop_back();
  store.save_session(stereo);
  expect_session_eq(*store.load_session(3), stereo);
  EXPECT_EQ(store.load_trajectory(3).size(), 1u);

  // The schema refuses an invalid calibration; the stored session is unchanged.
  SessionInfo invalid = stereo;
  invalid.cameras[0].fx = 0;
  EXPECT_THROW(store.save_session(invalid), Error);
  expect_session_eq(*store.load_session(3), stereo);
}

// Session records (session_record.h): every field, a replaced record, values
// the schema refuses (the stored record unchanged), and none for a session
// without one.
TEST_P(PersistenceBackends, SessionRecordsRoundTrip) {
  AtlasStore store = open_store(test_vocabulary().hash());
  for (const SessionId id : {2u, 5u, 7u}) {
    SessionInfo s;
    s.id = id;
    s.name = "session " + std::to_string(id);
    store.save_session(s);
  }
  SessionRecord finished;
  finished.frames = 3'682;
  finished.tracked = 3'675;
  finished.keyframes = 311;
  finished.rejected_frames = 2;
  finished.skipped_frames = 5;
  finished.maps_busy_frames = 4;
  finished.imu_samples = 36'820;
  finished.mode = "map";
  finished.config = "euroc/stereo_inertial";
  finished.outcome = "finished";
  finished.ended_by = "idle_timeout";
  SessionRecord failed;
  failed.frames = 40;
  failed.tracked = 12;
  failed.mode = "localize";
  failed.outcome = "failed";
  failed.error = "tracking failed 20 times in a row: out of memory";
  SessionRecord starting;  // as the server stores it before the first frame
  starting.mode = "map";
  starting.config = "";
  store.save_session_record(5, finished);
  store.save_session_record(2, failed);
  store.save_session_record(7, starting);
  auto records = store.load_session_records();
  ASSERT_EQ(records.size(), 3u);
  EXPECT_EQ(records.at(5), finished);
  EXPECT_EQ(records.at(2), failed);
  EXPECT_EQ(records.at(7), starting);
  EXPECT_EQ(records.at(7).outcome, "active");
  // Written again: replaced.
  starting.frames = starting.tracked = 200;
  starting.keyframes = 9;
  store.save_session_record(7, starting);
  EXPECT_EQ(store.load_session_records().at(7), starting);
  // Refused: more tracked than frames, an unknown outcome or mode, no such session.
  SessionRecord bad = starting;
  bad.tracked = bad.frames + 1;
  EXPECT_THROW(store.save_session_record(7, bad), Error);
  bad = starting;
  bad.outcome = "paused";
  EXPECT_THROW(store.save_session_record(7, bad), Error);
  bad = starting;
  bad.mode = "stereo";
  EXPECT_THROW(store.save_session_record(7, bad), Error);
  EXPECT_THROW(store.save_session_record(99, starting), Error);
  records = store.load_session_records();
  ASSERT_EQ(records.size(), 3u);
  EXPECT_EQ(records.at(7), starting);
}

// Upload jobs (job_rows.h): every field, optional ones absent and present,
// read as a list and one by id; a row written again replaces the stored one.
TEST_P(PersistenceBackends, JobsRoundTrip) {
  AtlasStore store = open_store(test_vocabulary().hash());
  SessionInfo session;  // a job's session must be stored (a foreign key)
  session.id = 12;
  session.name = "MH_02 upload";
  store.save_session(session);
  StoredJob done;
  done.id = 7;
  done.name = "MH_02 upload";
  done.state = "done";
  done.session = 12;
  done.created_ns = 1'700'000'000'987'654'321LL;
  done.archive_bytes = 1'234'567'890;
  done.frames_total = 2'999;
  done.frames_done = 2'999;
  done.tracked = 2'990;
  done.rejected = 3;
  done.ate_rmse_m = 0.0071;
  StoredJob failed;  // no session, no ATE
  failed.id = 2;
  failed.name = "";
  failed.state = "failed";
  failed.created_ns = 5;
  failed.error = "interrupted: the server stopped";
  store.save_job(done);
  store.save_job(failed);

  const std::vector<StoredJob> all = store.load_jobs();
  ASSERT_EQ(all.size(), 2u);
  EXPECT_EQ(all[0], failed);  // by id
  EXPECT_EQ(all[1], done);
  EXPECT_EQ(store.load_job(7), done);
  EXPECT_EQ(store.load_job(2), failed);
  EXPECT_FALSE(store.load_job(3).has_value());

  failed.state = "queued";
  failed.error.clear();
  failed.frames_done = 10;
  store.save_job(failed);
  EXPECT_EQ(store.load_job(2), failed);
  EXPECT_EQ(store.load_jobs().size(), 2u);
}

TEST_P(PersistenceBackends, TrajectoryRoundTrip) {
  AtlasStore store = open_store(test_vocabulary().hash());
  SessionInfo session;
  session.id = 2;
  store.save_session(session);
  std::mt19937_64 rng(21);
  std::vector<FrameAnchor> anchors;
  for (int i = 0; i < 300; ++i)
    anchors.push_back({1'403'636'579'763'555'584LL + 50'000'000LL * i, static_cast<MapId>(i / 100),
                       static_cast<KeyframeId>(rng() % 1000), random_pose(rng)});
  std::vector<FrameAnchor> shuffled = anchors;  // stored order does not matter: loaded by time
  std::shuffle(shuffled.begin(), shuffled.end(), rng);
  store.save_trajectory(2, shuffled);
  const auto check = [&](const std::vector<FrameAnchor>& loaded) {
    ASSERT_EQ(loaded.size(), anchors.size());
    for (std::size_t i = 0; i < anchors.size(); ++i) {
      EXPECT_EQ(loaded[i].t_ns, anchors[i].t_ns);
      EXPECT_EQ(loaded[i].map, anchors[i].map);
      EXPECT_EQ(loaded[i].reference, anchors[i].reference);
      expect_pose_eq(loaded[i].T_ref_b, anchors[i].T_ref_b, "anchor " + std::to_string(i));
    }
  };
  check(store.load_trajectory(2));
  EXPECT_TRUE(store.load_trajectory(5).empty());

  // A repeated timestamp is refused and the stored trajectory stays.
  std::vector<FrameAnchor> duplicate = {anchors[0], anchors[0]};
  EXPECT_THROW(store.save_trajectory(2, duplicate), Error);
  check(store.load_trajectory(2));
  // Saving again replaces.
  store.save_trajectory(2, {anchors[7]});
  ASSERT_EQ(store.load_trajectory(2).size(), 1u);
  EXPECT_EQ(store.load_trajectory(2)[0].t_ns, anchors[7].t_ns);
  // Unknown session.
  EXPECT_THROW(store.save_trajectory(6, anchors), Error);
}

}  // namespace
}  // namespace orbatlas
