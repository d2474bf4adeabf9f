// The atlas's SQLite schema: a fresh database, atlases of older schemas
// migrated forward with their rows, and the constraints the schema enforces.
#include <gtest/gtest.h>

#include <string>

#include "core/common/error.h"
#include "core/map/atlas.h"
#include "core/persistence/atlas_store.h"
#include "core/persistence/schema_migrations.h"
#include "core/persistence/sqlite_db.h"
#include "tests/persistence/test_persistence_expect.h"
#include "tests/persistence/schema_rollback.h"
#include "tests/persistence/test_persistence_random_atlas.h"
#include "tests/support/persistence_sessions.h"

namespace orbatlas {
namespace {

using namespace test;  // NOLINT: the shared helpers of the persistence tests

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
        "DELETE FROM schema_migrations WHERE version >= 6; PRAGMA user_version = 5; " +
        std::string(kUndoSchema18Sqlite) + "COMMIT");
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

// Schema 17 added maps_busy_frames to session_records: a record of schema 16
// keeps its counts and reads 0 there, and takes the count once migrated (and
// migrated on through 18, whose columns the rollback drops too).
TEST(Persistence, ASessionRecordOfSchemaSixteenGetsItsMapsBusyCount) {
  TempDb db("v16");
  SessionInfo session;
  session.id = 5;
  session.name = "live";
  session.sensor = SensorType::kStereo;
  SessionRecord record;
  record.frames = 120;
  record.tracked = 117;
  record.skipped_frames = 3;
  record.maps_busy_frames = 2;
  record.mode = "map";
  record.outcome = "finished";
  {
    AtlasStore store = AtlasStore::open(db.path(), test_vocabulary().hash());
    store.save_session(session);
    store.save_session_record(5, record);
  }
  {
    SqliteDb raw(db.path());
    raw.exec(std::string("BEGIN; ALTER TABLE session_records DROP COLUMN maps_busy_frames; ") + kUndoSchema18Sqlite +
             "DELETE FROM schema_migrations WHERE version >= 17; PRAGMA user_version = 16; COMMIT");
  }
  AtlasStore store = AtlasStore::open(db.path(), test_vocabulary().hash());
  EXPECT_EQ(store.schema_version(), latest_schema_version());
  SessionRecord expected = record;
  expected.maps_busy_frames = 0;
  EXPECT_EQ(store.load_session_records().at(5), expected);
  store.save_session_record(5, record);
  EXPECT_EQ(store.load_session_records().at(5), record);
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
