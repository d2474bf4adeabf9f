// Persistent atlas: SQLite schema, Cereal blobs, save / load round trips (on
// SQLite and on PostgreSQL: PersistenceBackends), and the refusals that must
// leave a file untouched.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <numeric>
#include <random>
#include <string>

#include "core/common/error.h"
#include "core/map/atlas.h"
#include "core/persistence/atlas_store.h"
#include "core/persistence/blob_codec.h"
#include "core/persistence/schema_migrations.h"
#include "core/persistence/sqlite_db.h"
#include "tests/support/persistence_backends.h"
#include "tests/persistence/test_persistence_expect.h"
#include "tests/persistence/test_persistence_random_atlas.h"

namespace orbatlas {
namespace {

namespace fs = std::filesystem;
using namespace test;  // NOLINT: the shared helpers of the persistence tests

constexpr const char* kOtherHash = "00000000deadbeef";

std::string file_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  EXPECT_TRUE(in.good()) << path;
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void write_file(const fs::path& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

template <class F>
std::string data_error_message(F&& f) {
  try {
    f();
  } catch (const DataError& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected DataError, got another exception: " << e.what();
    return {};
  }
  ADD_FAILURE() << "expected DataError, nothing thrown";
  return {};
}

// The tests whose bodies run on both backends (tests/support/persistence_backends.h).
using PersistenceBackends = AtlasBackendTest;
ORBATLAS_PERSISTENCE_BACKENDS(PersistenceBackends);

// --- tests ---

TEST(Persistence, FreshDatabaseHasTheLatestSchemaInWalMode) {
  TempDb db("fresh");
  TimestampNs created = 0;
  {
    AtlasStore store = AtlasStore::open(db.path(), test_vocabulary().hash());
    EXPECT_EQ(store.schema_version(), latest_schema_version());
    EXPECT_EQ(store.vocabulary_hash(), test_vocabulary().hash());
    EXPECT_GT(store.created_ns(), 0);
    created = store.created_ns();
    EXPECT_TRUE(store.stored_map_ids().empty());
  }
  ASSERT_EQ(schema_migrations().size(), static_cast<std::size_t>(latest_schema_version()));
  EXPECT_EQ(schema_migrations()[0].name, "001_initial");
  EXPECT_EQ(schema_migrations()[1].name, "002_culled_keyframes");
  SqliteDb raw(db.path());
  EXPECT_EQ(raw.query_int64("PRAGMA user_version"), latest_schema_version());
  SqliteStatement mode = raw.prepare("PRAGMA journal_mode");
  ASSERT_TRUE(mode.step());
  EXPECT_EQ(mode.text(0), "wal");
  EXPECT_EQ(raw.query_int64("SELECT count(*) FROM schema_migrations WHERE version = 1"), 1);
  EXPECT_EQ(raw.query_int64("SELECT checkpoint_seq FROM atlas"), 0);
  // Reopening neither migrates again nor recreates the atlas row.
  AtlasStore again = AtlasStore::open(db.path(), test_vocabulary().hash());
  EXPECT_EQ(again.created_ns(), created);
  EXPECT_EQ(raw.query_int64("SELECT count(*) FROM schema_migrations"), latest_schema_version());
}

// An atlas written by a build that knew only schema 1 (no culled keyframes, no
// checkpoint sequence) opens, migrates and keeps its rows.
TEST(Persistence, VersionOneAtlasMigratesForward) {
  TempDb db("v1");
  Atlas atlas;
  build_atlas(atlas, test_vocabulary(), 16);
  {
    AtlasStore store = AtlasStore::open(db.path(), test_vocabulary().hash());
    store.save_atlas(atlas);
  }
  {
    // Back to what schema 1 held: its tables and rows, user_version 1.
    SqliteDb raw(db.path());
    raw.exec(
        "PRAGMA foreign_keys = OFF; BEGIN; DROP TABLE session_records; DROP TABLE keyframe_imu_states; DROP TABLE "
        "keyframe_inertial_links; DROP "
        "TABLE map_inertial_states; "
        "DROP TABLE upload_jobs; DROP TRIGGER keyframes_not_culled; "
        "DROP TABLE culled_keyframes; ALTER TABLE keyframes DROP COLUMN units; ALTER TABLE atlas DROP COLUMN "
        "checkpoint_seq; DELETE FROM schema_migrations WHERE version >= 2; PRAGMA user_version = 1; COMMIT");
    ASSERT_EQ(raw.query_int64("SELECT count(*) FROM sqlite_schema WHERE name = 'keyframes_not_culled'"), 0);
  }
  AtlasStore store = AtlasStore::open(db.path(), test_vocabulary().hash());
  EXPECT_EQ(store.schema_version(), latest_schema_version());
  EXPECT_EQ(store.checkpoint_sequence(), 0);
  EXPECT_TRUE(store.load_jobs().empty());
  Atlas loaded;
  const AtlasLoadReport report = store.load_atlas(loaded, nullptr);
  EXPECT_EQ(report.keyframes, count_keyframes(atlas));
  EXPECT_EQ(report.map_points, count_points(atlas));
  EXPECT_EQ(report.culled_keyframes, 0u);  // schema 1 had nowhere to keep them
  store.save_atlas(atlas);
  EXPECT_EQ(store.checkpoint_sequence(), 1);
  Atlas again;
  store.load_atlas(again, nullptr);
  expect_atlas_eq(atlas, again, false);
}

TEST_P(PersistenceBackends, AtlasRoundTripKeepsEveryField) {
  const Vocabulary& vocabulary = test_vocabulary();
  Atlas original;
  build_atlas(original, vocabulary, 11);
  ASSERT_GT(original.counters()->keyframes().culled, 0u);
  ASSERT_GT(original.counters()->map_points().culled, 0u);
  // The content is non-trivial where the loader has most to get right.
  int asymmetric = 0, redundant = 0;
  for (const auto& kf : original.maps()[0]->keyframes()) {
    redundant += kf->redundant_map_point_count();
    for (const CovisibilityEdge& edge : kf->connections())
      if (const auto other = original.maps()[0]->keyframe(edge.keyframe);
          other && other->weight(kf->id()) != edge.weight)
        ++asymmetric;
  }
  EXPECT_GT(asymmetric, 0);
  EXPECT_GT(redundant, 0);
  {
    AtlasStore store = open_store(vocabulary.hash());
    store.save_atlas(original);
  }
  AtlasStore store = open_store(vocabulary.hash());
  EXPECT_EQ(store.stored_map_ids().size(), 3u);
  Atlas loaded;
  const AtlasLoadReport report = store.load_atlas(loaded, &vocabulary);
  EXPECT_EQ(report.maps, 3u);
  EXPECT_EQ(report.keyframes, count_keyframes(original));
  EXPECT_EQ(report.map_points, count_points(original));
  EXPECT_EQ(report.loop_edges, 2u);  // ka[0]-ka[8] and kb[1]-kb[3]; ka[1]-ka[3] went with ka[3]
  EXPECT_GT(report.covisibility_links, 0u);
  EXPECT_GT(report.observations, 0u);
  EXPECT_EQ(report.culled_keyframes, 4u);  // ka[3], the chain ka[7] -> ka[6], and map b's root
  EXPECT_EQ(report.culled_keyframes, count_culled_keyframes(original));
  expect_atlas_eq(original, loaded, true);

  // Frames anchored to culled keyframes resolve to the same poses after the round
  // trip, through chains of culled parents and from a culled root.
  SessionInfo session;
  session.id = 1;
  store.save_session(session);
  std::vector<FrameAnchor> anchors;
  std::mt19937_64 frame_rng(17);
  for (const auto& map : original.maps())
    for (const Map::CulledKeyframe& c : map->culled_keyframes())
      anchors.push_back(
          {static_cast<TimestampNs>(anchors.size()) * 50'000'000, map->id(), c.id, random_pose(frame_rng)});
  ASSERT_EQ(anchors.size(), 4u);
  store.save_trajectory(session.id, anchors);
  for (const FrameAnchor& a : store.load_trajectory(session.id)) {
    const auto before = original.map(a.map)->keyframe_pose(a.reference);
    const auto after = loaded.map(a.map)->keyframe_pose(a.reference);
    ASSERT_TRUE(before && after) << "keyframe " << a.reference;
    expect_pose_eq(*before * a.T_ref_b, *after * a.T_ref_b, "frame at " + std::to_string(a.t_ns));
  }
  EXPECT_EQ(store.checkpoint_sequence(), 1);  // one save_atlas

  // Nothing loaded is culled; the counters count what was created by loading.
  EXPECT_EQ(loaded.counters()->keyframes().created, count_keyframes(original));
  EXPECT_EQ(loaded.counters()->keyframes().culled, 0u);
  EXPECT_EQ(loaded.counters()->map_points().created, count_points(original));

  // New ids continue above everything the original atlas handed out, including
  // the culled keyframe and point that had the largest ids.
  const auto map_b = loaded.map(original.maps()[1]->id());
  ASSERT_NE(map_b, nullptr);
  KeyframeId max_loaded_kf = 0;
  for (const auto& m : loaded.maps())
    for (const auto& kf : m->keyframes()) max_loaded_kf = std::max(max_loaded_kf, kf->id());
  const KeyframeId new_kf = map_b->new_keyframe(KeyFrameData{})->id();
  EXPECT_EQ(new_kf, original.ids().peek(IdKind::keyframe));
  EXPECT_GT(new_kf, max_loaded_kf + 1);  // the culled last keyframe's id is skipped
  EXPECT_EQ(map_b->new_map_point({})->id(), original.ids().peek(IdKind::map_point));
  EXPECT_EQ(loaded.create_map()->id(), original.ids().peek(IdKind::map));

  // Loading needs an empty atlas and the store's vocabulary.
  EXPECT_THROW(store.load_atlas(loaded, &vocabulary), Error);
  Atlas other;
  std::mt19937_64 rng(5);
  std::vector<std::vector<Descriptor>> images(2);
  for (auto& image : images)
    for (int i = 0; i < 30; ++i) image.push_back(random_descriptor(rng));
  VocabularyTrainingOptions options;
  options.k = 3;
  options.levels = 2;
  options.threads = 1;
  const Vocabulary foreign = Vocabulary::train(images, options);
  ASSERT_NE(foreign.hash(), vocabulary.hash());
  EXPECT_THROW(store.load_atlas(other, &foreign), Error);
  EXPECT_TRUE(other.maps().empty());
}

TEST_P(PersistenceBackends, LoadingWithoutVocabularyLeavesBowEmpty) {
  Atlas original;
  build_atlas(original, test_vocabulary(), 12);
  AtlasStore store = open_store(test_vocabulary().hash());
  store.save_atlas(original);
  Atlas loaded;
  store.load_atlas(loaded, nullptr);
  expect_atlas_eq(original, loaded, false);
}

// One map read again (a replica taking over another's map): the
// stored version, into a detached map the atlas then takes in place of its own
// copy, not recorded as removed.
TEST_P(PersistenceBackends, OneMapIsReadAgainAsStored) {
  Atlas original;
  build_atlas(original, test_vocabulary(), 14);
  AtlasStore store = open_store(test_vocabulary().hash());
  store.save_atlas(original);
  Atlas stored;
  store.load_atlas(stored, &test_vocabulary());
  const auto map = original.maps()[1];
  map->map_points()[0]->set_p_w({4, 5, 6});  // edited after the save: not what is read
  const auto fresh = store.load_map(original, map->id(), &test_vocabulary());
  ASSERT_NE(fresh, nullptr);
  EXPECT_EQ(original.map(map->id()), map);  // not in the atlas yet
  expect_map_eq(*stored.map(map->id()), *fresh, true);
  EXPECT_EQ(store.load_map(original, 424242, &test_vocabulary()), nullptr);
  {
    const auto whole = original.lock_maps_exclusive();
    EXPECT_EQ(original.replace_map(fresh), map);
  }
  EXPECT_EQ(original.map(map->id()), fresh);
  EXPECT_TRUE(original.removed_maps().empty());
  expect_atlas_eq(stored, original, true);
}

TEST_P(PersistenceBackends, SavingAgainReplacesTheStoredMaps) {
  const Vocabulary& vocabulary = test_vocabulary();
  Atlas atlas;
  build_atlas(atlas, vocabulary, 13);
  AtlasStore store = open_store(vocabulary.hash());
  SessionInfo session;
  session.id = 7;
  session.name = "MH_01";
  store.save_session(session);

  const auto map_a = atlas.maps()[0];
  const auto kfs = map_a->keyframes();
  AtlasSaveOptions options;
  options.keyframe_sessions[kfs[0]->id()] = 7;
  options.keyframe_sessions[kfs[2]->id()] = 7;
  store.save_atlas(atlas, options);

  // Edit: cull a keyframe and a point, move a keyframe, change a point.
  ASSERT_TRUE(map_a->cull_keyframe(kfs[1]->id()));
  const auto points = map_a->map_points();
  ASSERT_TRUE(map_a->cull_map_point(points[5]->id()));
  kfs[4]->set_T_w_b(Pose3(Eigen::Quaterniond(0.5, 0.5, -0.5, 0.5), Eigen::Vector3d(1, 2, 3)));
  points[6]->set_p_w({9, 8, 7});
  points[6]->increase_found(3);
  store.save_atlas(atlas);  // no session options: the stored ones stay
  int dead_links = 0;       // see expect_keyframe_eq
  for (const auto& kf : map_a->keyframes())
    for (const CovisibilityEdge& edge : kf->connections()) dead_links += map_a->keyframe(edge.keyframe) ? 0 : 1;
  EXPECT_GT(dead_links, 0);

  Atlas loaded;
  const AtlasLoadReport report = store.load_atlas(loaded, &vocabulary);
  expect_atlas_eq(atlas, loaded, true);
  EXPECT_EQ(loaded.map(map_a->id())->keyframe(kfs[1]->id()), nullptr);
  EXPECT_EQ(report.keyframe_sessions.size(), 2u);
  EXPECT_EQ(report.keyframe_sessions.at(kfs[0]->id()), 7u);
  EXPECT_EQ(report.keyframe_sessions.at(kfs[2]->id()), 7u);

  // A map stored earlier but no longer in the atlas stays stored.
  Atlas small;
  small.add_map(100);
  store.save_atlas(small);
  std::vector<MapId> ids = store.stored_map_ids();
  EXPECT_EQ(ids.size(), 4u);
  EXPECT_EQ(ids.back(), 100u);
  // A keyframe session naming no stored session is refused, and nothing changes.
  AtlasSaveOptions bad;
  bad.keyframe_sessions[kfs[0]->id()] = 999;
  EXPECT_THROW(store.save_atlas(atlas, bad), Error);
  Atlas reloaded;
  EXPECT_EQ(store.load_atlas(reloaded, nullptr).keyframe_sessions.size(), 2u);
}

CameraCalibration camera(CameraModel model, std::vector<double> distortion, double shift) {
  CameraCalibration c;
  c.model = model;
  c.fx = 458.654 + shift;
  c.fy = 457.296 + shift;
  c.cx = 367.215;
  c.cy = 248.375;
  c.distortion = std::move(distortion);
  c.width = 752;
  c.height = 480;
  c.rate_hz = 20.0;
  c.T_b_c =
      Pose3(Eigen::Quaterniond(0.7123, -0.0077, 0.0105, 0.7018), Eigen::Vector3d(-0.0216, -0.0647, 0.0098 + shift));
  return c;
}

void expect_session_eq(const SessionInfo& a, const SessionInfo& b) {
  EXPECT_EQ(a.id, b.id);
  EXPECT_EQ(a.name, b.name);
  EXPECT_EQ(a.sensor, b.sensor);
  EXPECT_EQ(a.created_ns, b.created_ns);
  ASSERT_EQ(a.cameras.size(), b.cameras.size());
  for (std::size_t i = 0; i < a.cameras.size(); ++i) {
    const CameraCalibration &ca = a.cameras[i], &cb = b.cameras[i];
    EXPECT_EQ(ca.model, cb.model);
    EXPECT_EQ(ca.fx, cb.fx);
    EXPECT_EQ(ca.fy, cb.fy);
    EXPECT_EQ(ca.cx, cb.cx);
    EXPECT_EQ(ca.cy, cb.cy);
    EXPECT_EQ(ca.distortion, cb.distortion);
    EXPECT_EQ(ca.width, cb.width);
    EXPECT_EQ(ca.height, cb.height);
    EXPECT_EQ(ca.rate_hz, cb.rate_hz);
    expect_pose_eq(ca.T_b_c, cb.T_b_c, "T_b_c");
  }
}

// Schema 6 rebuilt `sessions` to admit the rgbd sensor: an atlas of schema 5
// keeps every session with its cameras and trajectory (the rebuild must not
// cascade into them), and takes an RGB-D session afterwards.
TEST(Persistence, VersionFiveSessionsSurviveTheRebuildForRgbd) {
  TempDb db("v5");
  SessionInfo stereo;
  stereo.id = 3;
  stereo.name = "stereo";
  stereo.sensor = SensorType::kStereo;
  stereo.created_ns = 17;
  stereo.cameras = {camera(CameraModel::kPinholeRadTan, {-0.28, 0.07, 0.0002, 1.7e-05}, 0),
                    camera(CameraModel::kPinholeRadTan, {-0.28, 0.07, -0.0001, -3.5e-05}, 1)};
  {
    AtlasStore store = AtlasStore::open(db.path(), test_vocabulary().hash());
    store.save_session(stereo);
    store.save_trajectory(3, {FrameAnchor{100, 0, 1, Pose3()}, FrameAnchor{200, 0, 1, Pose3()}});
  }
  {
    // Back to schema 5's sessions table (its CHECK without rgbd), user_version 5.
    SqliteDb raw(db.path());
    raw.exec(
        "PRAGMA foreign_keys = OFF; BEGIN; DROP TABLE session_records; CREATE TABLE s5 (id INTEGER PRIMARY KEY CHECK "
        "(id >= 0), name TEXT NOT "
        "NULL, sensor TEXT NOT NULL CHECK (sensor IN ('mono', 'stereo', 'mono_inertial', 'stereo_inertial')), "
        "created_ns INTEGER NOT NULL) STRICT; INSERT INTO s5 SELECT * FROM sessions; DROP TABLE sessions; ALTER "
        "TABLE s5 RENAME TO sessions; ALTER TABLE keyframes DROP COLUMN units; ALTER TABLE culled_keyframes DROP "
        "COLUMN units; ALTER TABLE keyframe_inertial_links DROP COLUMN c_i_qw; ALTER TABLE keyframe_inertial_links "
        "DROP COLUMN c_i_qx; ALTER TABLE keyframe_inertial_links DROP COLUMN c_i_qy; ALTER TABLE "
        "keyframe_inertial_links DROP COLUMN c_i_qz; ALTER TABLE keyframe_inertial_links DROP COLUMN c_i_tx; ALTER "
        "TABLE keyframe_inertial_links DROP COLUMN c_i_ty; ALTER TABLE keyframe_inertial_links DROP COLUMN c_i_tz; "
        "DELETE FROM schema_migrations WHERE version >= 6; PRAGMA user_version = 5; "
        "COMMIT");
    EXPECT_THROW(raw.exec("INSERT INTO sessions VALUES (4, 'x', 'rgbd', 0)"), Error);
  }
  AtlasStore store = AtlasStore::open(db.path(), test_vocabulary().hash());
  EXPECT_EQ(store.schema_version(), latest_schema_version());
  const auto kept = store.load_session(3);
  ASSERT_TRUE(kept.has_value());
  expect_session_eq(*kept, stereo);  // its cameras too
  EXPECT_EQ(store.load_trajectory(3).size(), 2u);
  SessionInfo rgbd;
  rgbd.id = 4;
  rgbd.name = "rgbd";
  rgbd.sensor = SensorType::kRgbd;
  rgbd.cameras = {camera(CameraModel::kPinholeRadTan, {0.1, -0.2, 0.0, 0.0}, 0)};
  store.save_session(rgbd);
  expect_session_eq(*store.load_session(4), rgbd);
  // Foreign keys are on again for the connection: a trajectory of no session is refused.
  EXPECT_THROW(store.save_trajectory(99, {FrameAnchor{1, 0, 1, Pose3()}}), Error);
}

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

// Opening refuses, before writing anything, another application's database and
// an atlas of another vocabulary (the file-level refusals are SQLite's, below).
TEST_P(PersistenceBackends, OpeningRefusesAnotherApplicationsDatabaseAndAnotherVocabulary) {
  const std::unique_ptr<SqlConnection> raw = raw_connection();
  raw->exec("CREATE TABLE notes (id bigint PRIMARY KEY)");
  std::string message = data_error_message([&] { open_store(test_vocabulary().hash()); });
  EXPECT_NE(message.find("not an orbatlas atlas"), std::string::npos) << message;
  EXPECT_THROW(raw->query_int64("SELECT count(*) FROM atlas"), Error);  // nothing created
  raw->exec("DROP TABLE notes");

  { open_store(test_vocabulary().hash()).save_session(SessionInfo{}); }
  message = data_error_message([&] { open_store(kOtherHash); });
  EXPECT_NE(message.find("vocabulary"), std::string::npos) << message;
  EXPECT_NE(message.find(test_vocabulary().hash()), std::string::npos) << message;
  EXPECT_NE(message.find(kOtherHash), std::string::npos) << message;
  EXPECT_EQ(open_store(test_vocabulary().hash()).load_sessions().size(), 1u);
}

TEST(Persistence, ForeignVocabularyIsRefusedAndTheFileIsUntouched) {
  TempDb db("foreign_vocabulary");
  Atlas atlas;
  build_atlas(atlas, test_vocabulary(), 14);
  {
    AtlasStore store = AtlasStore::open(db.path(), test_vocabulary().hash());
    store.save_atlas(atlas);
  }
  ASSERT_FALSE(fs::exists(db.companion("-wal")));  // checkpointed on close
  const std::string before = file_bytes(db.path());
  const std::string message = data_error_message([&] { AtlasStore::open(db.path(), kOtherHash); });
  EXPECT_NE(message.find("vocabulary"), std::string::npos) << message;
  EXPECT_NE(message.find(test_vocabulary().hash()), std::string::npos) << message;
  EXPECT_EQ(file_bytes(db.path()), before);
  EXPECT_FALSE(fs::exists(db.companion("-wal")));
  // The same for an atlas in rollback-journal mode (e.g. copied with a tool that
  // changed it): the refusal comes before switching to WAL, which would rewrite
  // the header.
  {
    SqliteDb raw(db.path());
    SqliteStatement mode = raw.prepare("PRAGMA journal_mode = DELETE");
    ASSERT_TRUE(mode.step());
    ASSERT_EQ(mode.text(0), "delete");
  }
  const std::string rollback_mode = file_bytes(db.path());
  EXPECT_NE(rollback_mode, before);  // the header records the journal mode
  EXPECT_NE(data_error_message([&] { AtlasStore::open(db.path(), kOtherHash); }).find("vocabulary"), std::string::npos);
  EXPECT_EQ(file_bytes(db.path()), rollback_mode);
  // The right vocabulary still opens it.
  AtlasStore store = AtlasStore::open(db.path(), test_vocabulary().hash());
  Atlas loaded;
  store.load_atlas(loaded, nullptr);
  EXPECT_EQ(count_keyframes(loaded), count_keyframes(atlas));
}

TEST(Persistence, NewerSchemaIsRefusedAndTheFileIsUntouched) {
  TempDb db("newer_schema");
  { AtlasStore::open(db.path(), test_vocabulary().hash()); }
  {
    SqliteDb raw(db.path());
    raw.exec("PRAGMA user_version = " + std::to_string(latest_schema_version() + 1));
  }
  const std::string before = file_bytes(db.path());
  const std::string message = data_error_message([&] { AtlasStore::open(db.path(), test_vocabulary().hash()); });
  EXPECT_NE(message.find("newer"), std::string::npos) << message;
  EXPECT_EQ(file_bytes(db.path()), before);
}

TEST(Persistence, NonAtlasFilesAreRefusedAndUntouched) {
  // A text file.
  TempDb text("not_sqlite");
  std::string junk = "this is not an SQLite database but a plain text file\n";
  for (int i = 0; i < 6; ++i) junk += junk;
  write_file(text.path(), junk);
  const std::string message = data_error_message([&] { AtlasStore::open(text.path(), test_vocabulary().hash()); });
  EXPECT_NE(message.find("not an SQLite database"), std::string::npos) << message;
  EXPECT_NE(message.find(text.path().string()), std::string::npos) << message;
  EXPECT_EQ(file_bytes(text.path()), junk);

  // Another application's SQLite database.
  TempDb foreign("foreign_sqlite");
  {
    SqliteDb raw(foreign.path());
    raw.exec("CREATE TABLE notes(id INTEGER PRIMARY KEY, body TEXT); INSERT INTO notes(body) VALUES ('hello')");
  }
  const std::string before = file_bytes(foreign.path());
  const std::string m2 = data_error_message([&] { AtlasStore::open(foreign.path(), test_vocabulary().hash()); });
  EXPECT_NE(m2.find("not an orbatlas atlas"), std::string::npos) << m2;
  EXPECT_EQ(file_bytes(foreign.path()), before);

  // A folder that does not exist: a plain Error naming the path.
  const fs::path missing = fs::temp_directory_path() / "orbatlas_no_such_folder_for_test" / "atlas.db";
  EXPECT_THROW(AtlasStore::open(missing, test_vocabulary().hash()), Error);
}

TEST(Persistence, CorruptBlobsAreDataErrors) {
  TempDb db("corrupt");
  Atlas atlas;
  build_atlas(atlas, test_vocabulary(), 15);
  const KeyframeId victim = atlas.maps()[0]->keyframes()[2]->id();
  const MapPointId point = atlas.maps()[0]->map_points()[0]->id();
  {
    AtlasStore store = AtlasStore::open(db.path(), test_vocabulary().hash());
    store.save_atlas(atlas);
  }
  const auto tamper_and_load = [&](const std::string& sql) {
    {
      AtlasStore store = AtlasStore::open(db.path(), test_vocabulary().hash());
      store.save_atlas(atlas);  // restore the sound rows first
    }
    {
      SqliteDb raw(db.path());
      raw.exec(sql);
    }
    AtlasStore store = AtlasStore::open(db.path(), test_vocabulary().hash());
    Atlas loaded;
    return data_error_message([&] { store.load_atlas(loaded, &test_vocabulary()); });
  };
  const std::string where = " WHERE id = " + std::to_string(victim);
  std::string m = tamper_and_load("UPDATE keyframes SET features = substr(features, 1, 200)" + where);
  EXPECT_NE(m.find("truncated"), std::string::npos) << m;
  EXPECT_NE(m.find("keyframe " + std::to_string(victim)), std::string::npos) << m;
  m = tamper_and_load("UPDATE keyframes SET features = CAST(X'09000000' || substr(features, 5) AS BLOB)" + where);
  EXPECT_NE(m.find("unknown version 9"), std::string::npos) << m;
  m = tamper_and_load("UPDATE keyframes SET features = CAST(features || X'00' AS BLOB)" + where);
  EXPECT_NE(m.find("trailing"), std::string::npos) << m;
  m = tamper_and_load("UPDATE keyframes SET features = X''" + where);
  EXPECT_NE(m.find("version tag"), std::string::npos) << m;
  m = tamper_and_load("UPDATE keyframes SET slot_count = slot_count + 1" + where);
  EXPECT_NE(m.find("slot_count"), std::string::npos) << m;
  // The schema keeps a descriptor at 32 bytes; with the CHECK bypassed, the codec does.
  m = tamper_and_load("PRAGMA ignore_check_constraints = ON; UPDATE map_points SET descriptor = X'0102' WHERE id = " +
                      std::to_string(point));
  EXPECT_NE(m.find("descriptor"), std::string::npos) << m;

  // Culled keyframes whose chain of parents cannot be resolved.
  std::int64_t culled = 0, chained = 0;
  {
    SqliteDb raw(db.path());
    chained = raw.query_int64("SELECT id FROM culled_keyframes WHERE parent_id IN (SELECT id FROM culled_keyframes)");
    culled = raw.query_int64("SELECT parent_id FROM culled_keyframes WHERE id = " + std::to_string(chained));
  }
  m = tamper_and_load("UPDATE culled_keyframes SET parent_id = 999999 WHERE id = " + std::to_string(culled));
  EXPECT_NE(m.find("parent 999999 is neither"), std::string::npos) << m;
  m = tamper_and_load("UPDATE culled_keyframes SET parent_id = " + std::to_string(chained) +
                      " WHERE id = " + std::to_string(culled));
  EXPECT_NE(m.find("cycle"), std::string::npos) << m;
}

TEST(Persistence, FeaturesBlobRejectsEveryTruncation) {
  std::mt19937_64 rng(31);
  const ImageFeatures features = random_features(rng, 5);
  const std::vector<float> depth = {1, -1, 2, 3, -1}, u_right = {10, -1, 20, 30, -1};
  const std::string blob = encode_features(features, depth, u_right);
  const StoredFeatures decoded = decode_features(blob, "test");
  EXPECT_EQ(decoded.features.descriptors, features.descriptors);
  EXPECT_EQ(decoded.depth, depth);
  EXPECT_EQ(decoded.u_right, u_right);
  for (std::size_t n = 0; n < blob.size(); ++n)
    EXPECT_THROW(decode_features(std::string_view(blob).substr(0, n), "test"), DataError) << n << " bytes";
  // A huge announced keypoint count is refused before anything is allocated.
  std::string huge = blob;
  const std::uint64_t count = 1ULL << 60;
  std::memcpy(huge.data() + 12, &count, sizeof(count));
  EXPECT_THROW(decode_features(huge, "test"), DataError);
  // Monocular, no descriptors, no keypoints: all round-trip.
  const StoredFeatures empty = decode_features(encode_features(ImageFeatures{}, {}, {}), "test");
  EXPECT_TRUE(empty.features.keypoints.empty());
  EXPECT_THROW(encode_features(features, {1.0f}, {1.0f}), Error);  // stereo vectors of the wrong size
  EXPECT_THROW(decode_descriptor("short", "test"), DataError);
  EXPECT_THROW(decode_doubles("1234567", "test"), DataError);
}

TEST(Persistence, SchemaConstraintsHold) {
  TempDb db("constraints");
  { AtlasStore::open(db.path(), test_vocabulary().hash()); }
  SqliteDb raw(db.path());
  raw.exec("PRAGMA foreign_keys = ON");
  raw.exec("INSERT INTO sessions(id, name, sensor, created_ns) VALUES (1, 's', 'stereo', 0)");
  raw.exec("INSERT INTO maps(id, saved_ns) VALUES (1, 0)");
  // Quaternion norm, sensor names, slot ranges, foreign keys, the observation trigger.
  EXPECT_THROW(raw.exec("INSERT INTO trajectory VALUES (1, 5, 0, 0, 2, 0, 0, 0, 0, 0, 0)"), Error);
  raw.exec("INSERT INTO trajectory VALUES (1, 5, 0, 0, 1, 0, 0, 0, 0, 0, 0)");
  EXPECT_THROW(raw.exec("INSERT INTO sessions(id, name, sensor, created_ns) VALUES (2, 's', 'lidar', 0)"), Error);
  EXPECT_THROW(raw.exec("INSERT INTO trajectory VALUES (3, 5, 0, 0, 1, 0, 0, 0, 0, 0, 0)"), Error);  // no session 3
  raw.exec(
      "INSERT INTO keyframes(id, map_id, timestamp_ns, qw, qx, qy, qz, tx, ty, tz, "
      "c_qw, c_qx, c_qy, c_qz, c_tx, c_ty, c_tz, slot_count, features) "
      "VALUES (1, 1, 0, 1, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 4, X'')");
  raw.exec(
      "INSERT INTO map_points(id, map_id, x, y, z, nx, ny, nz, min_distance, max_distance, descriptor, visible, "
      "found) VALUES (1, 1, 0, 0, 0, 0, 0, 1, 1, 2, zeroblob(32), 1, 1)");
  EXPECT_THROW(raw.exec("INSERT INTO observations VALUES (1, 4, 1)"), Error);   // slot out of range
  EXPECT_THROW(raw.exec("INSERT INTO observations VALUES (1, -1, 1)"), Error);  // negative slot
  raw.exec("INSERT INTO observations VALUES (1, 3, 1)");
  EXPECT_THROW(raw.exec("INSERT INTO observations VALUES (1, 2, 1)"), Error);           // point already in slot 3
  EXPECT_THROW(raw.exec("UPDATE keyframes SET features = 'text, not a blob'"), Error);  // STRICT types
  EXPECT_THROW(raw.exec("UPDATE map_points SET descriptor = zeroblob(31)"), Error);
  // Culled keyframes: never alive at the same time, not their own parent, a unit quaternion.
  EXPECT_THROW(raw.exec("INSERT INTO culled_keyframes VALUES (1, 1, NULL, 1, 0, 0, 0, 0, 0, 0, 1)"), Error);
  EXPECT_THROW(raw.exec("INSERT INTO culled_keyframes VALUES (2, 1, 2, 1, 0, 0, 0, 0, 0, 0, 1)"), Error);
  EXPECT_THROW(raw.exec("INSERT INTO culled_keyframes VALUES (2, 1, 1, 0.5, 0, 0, 0, 0, 0, 0, 1)"), Error);
  EXPECT_THROW(raw.exec("INSERT INTO culled_keyframes VALUES (2, 7, 1, 1, 0, 0, 0, 0, 0, 0, 1)"), Error);  // no map 7
  EXPECT_THROW(raw.exec("INSERT INTO culled_keyframes VALUES (2, 1, 1, 1, 0, 0, 0, 0, 0, 0, 0)"), Error);  // units
  EXPECT_THROW(raw.exec("UPDATE keyframes SET units = -2"), Error);
  raw.exec("INSERT INTO culled_keyframes VALUES (2, 1, 1, 1, 0, 0, 0, 0, 0, 0, 1)");
  raw.exec("INSERT INTO culled_keyframes VALUES (3, 1, 2, 1, 0, 0, 0, 0, 0, 0, 1)");  // a chain 3 -> 2 -> 1
  EXPECT_THROW(raw.exec("INSERT INTO keyframes(id, map_id, timestamp_ns, qw, qx, qy, qz, tx, ty, tz, "
                        "c_qw, c_qx, c_qy, c_qz, c_tx, c_ty, c_tz, slot_count, features) "
                        "VALUES (2, 1, 0, 1, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 4, X'')"),
               Error);
  EXPECT_THROW(raw.exec("UPDATE atlas SET checkpoint_seq = -1"), Error);
  // Deleting the map cascades to everything in it, and not to the trajectory.
  raw.exec("DELETE FROM maps WHERE id = 1");
  EXPECT_EQ(raw.query_int64("SELECT count(*) FROM culled_keyframes"), 0);
  EXPECT_EQ(raw.query_int64("SELECT count(*) FROM keyframes"), 0);
  EXPECT_EQ(raw.query_int64("SELECT count(*) FROM observations"), 0);
  EXPECT_EQ(raw.query_int64("SELECT count(*) FROM trajectory"), 1);
}

}  // namespace
}  // namespace orbatlas
