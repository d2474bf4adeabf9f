// A visual-inertial map in the atlas database: the keyframes'
// inertial links (the IMU increments between them), their IMU states
// (velocity, biases) and the map's inertial state are stored and loaded equal;
// a save after culling stores the joined increments, a checkpoint a refined
// IMU state; a corrupt increments blob is a DataError. An atlas of schema 17
// (before the IMU's scale factors were stored) loads with no correction. On SQLite and on
// PostgreSQL (tests/support/persistence_backends.h).
#include <gtest/gtest.h>

#include <limits>
#include <random>

#include "core/common/error.h"
#include "core/persistence/atlas_checkpoint_writer.h"
#include "core/persistence/atlas_store.h"
#include "core/persistence/blob_codec.h"
#include "core/persistence/inertial_blob.h"
#include "core/persistence/schema_migrations.h"
#include "core/persistence/sqlite_db.h"
#include "tests/support/persistence_backends.h"
#include "tests/persistence/test_persistence_expect.h"
#include "tests/persistence/test_persistence_random_atlas.h"
#include "tests/persistence/schema_rollback.h"

namespace orbatlas {
namespace {

using namespace orbatlas::test;

std::shared_ptr<const Preintegration> random_increments(std::mt19937_64& rng, int steps) {
  std::normal_distribution<double> n(0.0, 1.0);
  ImuBias bias;
  bias.gyro = Eigen::Vector3d(0.001, -0.002, 0.003);
  bias.accel = Eigen::Vector3d(0.02, 0.01, -0.03);
  // With the vibration measured in flight (stored since blob version 2).
  ImuNoise noise;
  noise.vibration.rotation_var = Eigen::Vector3d(1.1e-7, 5.8e-7, 6.1e-7);
  noise.vibration.velocity_var = Eigen::Vector3d(6.1e-5, 1.0e-5, 2.3e-5);
  auto pre = std::make_shared<Preintegration>(bias, noise);
  for (int i = 0; i < steps; ++i)
    pre->integrate(Eigen::Vector3d(n(rng), n(rng), n(rng)) * 0.3, Eigen::Vector3d(n(rng), n(rng), 9.81 + n(rng)),
                   0.005);
  return pre;
}

std::shared_ptr<Map> inertial_map(Atlas& atlas, std::mt19937_64& rng, const Vocabulary& vocabulary,
                                  std::vector<std::shared_ptr<KeyFrame>>& kfs) {
  auto map = atlas.create_map();
  for (int k = 0; k < 5; ++k) kfs.push_back(add_random_keyframe(*map, rng, &vocabulary, 40, true));
  std::normal_distribution<double> n(0.0, 1.0);
  for (std::size_t k = 1; k < kfs.size(); ++k) {
    // The IMU in the camera on all but the first link (one stored before schema 8).
    std::optional<Pose3> T_c_i;
    if (k > 1)
      T_c_i = Pose3(Eigen::Quaterniond(0.5, -0.5, 0.5, -0.5),
                    Eigen::Vector3d(0.02, -0.065, 0.008 * static_cast<double>(k)));
    kfs[k]->set_inertial_link(kfs[k - 1], random_increments(rng, 60), T_c_i);
    KeyFrame::ImuState imu;
    imu.v_i = Eigen::Vector3d(n(rng), n(rng), n(rng));
    imu.bias.gyro = Eigen::Vector3d(n(rng), n(rng), n(rng)) * 0.001;
    imu.bias.accel = Eigen::Vector3d(n(rng), n(rng), n(rng)) * 0.01;
    kfs[k]->set_imu_state(imu);
  }
  Map::InertialState state;
  state.initialized_at_ns = 2'000'000'000;
  state.gravity_w = Eigen::Vector3d(0.0, 0.0, -9.81);
  state.bias.gyro = Eigen::Vector3d(0.0012, -0.0021, 0.0031);
  state.bias.accel = Eigen::Vector3d(0.021, 0.011, -0.029);
  state.keyframes = 5;
  state.span_s = 1.2;
  state.scale.gyro = Eigen::Vector3d(0.0011, -0.0007, 0.0023);
  state.scale.accel = Eigen::Vector3d(0.0019, -0.0004, 0.0031);
  map->set_inertial_state(state);
  return map;
}

using PersistenceInertial = AtlasBackendTest;
ORBATLAS_PERSISTENCE_BACKENDS(PersistenceInertial);

TEST_P(PersistenceInertial, LinksAndStatesRoundTripAndFollowCulling) {
  const Vocabulary& vocabulary = test_vocabulary();
  std::mt19937_64 rng(23);
  Atlas original;
  std::vector<std::shared_ptr<KeyFrame>> kfs;
  auto map = inertial_map(original, rng, vocabulary, kfs);
  original.create_map();  // a visual map next to it: no state, no links
  {
    AtlasStore store = open_store(vocabulary.hash());
    store.save_atlas(original);
  }
  {
    AtlasStore store = open_store(vocabulary.hash());
    Atlas loaded;
    const AtlasLoadReport report = store.load_atlas(loaded, &vocabulary);
    EXPECT_EQ(report.inertial_links, 4u);
    EXPECT_EQ(report.imu_states, 4u);  // the map's first keyframe has none
    expect_atlas_eq(original, loaded, true);
    ASSERT_TRUE(loaded.map(map->id())->inertial_state().has_value());
  }

  // Culling a keyframe of the chain joins its increments: the next write stores
  // the joined link (and the link of the culled one goes with its row).
  ASSERT_TRUE(map->cull_keyframe(kfs[2]->id()));
  ASSERT_EQ(kfs[3]->inertial_link()->previous_id, kfs[1]->id());
  Map::InertialState refined = *map->inertial_state();
  refined.bias.accel.x() = 0.05;
  refined.refinements = 1;
  map->set_inertial_state(refined);
  KeyFrame::ImuState moved = *kfs[4]->imu_state();  // as visual-inertial BA refines it
  moved.v_i.x() += 0.01;
  moved.bias.gyro.z() -= 1e-4;
  kfs[4]->set_imu_state(moved);
  {
    AtlasStore store = open_store(vocabulary.hash());
    store.save_atlas(original);
    Atlas loaded;
    const AtlasLoadReport report = store.load_atlas(loaded, &vocabulary);
    EXPECT_EQ(report.inertial_links, 3u);
    EXPECT_EQ(report.imu_states, 3u);
    expect_atlas_eq(original, loaded, true);
    EXPECT_EQ(loaded.map(map->id())->keyframe(kfs[3]->id())->inertial_link()->from_previous->dt(),
              kfs[3]->inertial_link()->from_previous->dt());
  }

  // A checkpoint writes a refined IMU state, and only that row (the first
  // checkpoint rewrites every map, as save_atlas does).
  {
    AtlasCheckpointWriter writer(original, open_store(vocabulary.hash()), std::nullopt);
    writer.set_durable(false);  // as AtlasCheckpointer's connection between its final checkpoints
    ASSERT_TRUE(writer.checkpoint().committed);
    KeyFrame::ImuState again = *kfs[1]->imu_state();
    again.v_i.z() -= 0.02;
    again.bias.accel.y() += 0.001;
    kfs[1]->set_imu_state(again);
    const CheckpointResult result = writer.checkpoint();
    ASSERT_TRUE(result.committed);
    EXPECT_EQ(result.rows.updated, 1u);
    EXPECT_EQ(result.rows.total(), 1u);
    // Local BA moved the IMU's scale-factor correction alone: the map's state
    // row is written, and only that.
    Map::InertialState rescaled = *map->inertial_state();
    rescaled.scale.accel.y() = 0.0042;
    map->set_inertial_state(rescaled);
    const CheckpointResult scaled = writer.checkpoint();
    ASSERT_TRUE(scaled.committed);
    EXPECT_EQ(scaled.rows.updated, 1u);
    EXPECT_EQ(scaled.rows.total(), 1u);
    AtlasStore store = open_store(vocabulary.hash());
    Atlas loaded;
    store.load_atlas(loaded, &vocabulary);
    expect_atlas_eq(original, loaded, true);
    EXPECT_EQ(loaded.map(map->id())->inertial_state()->scale.accel.y(), 0.0042);
  }

  // Each of these stored values makes the load fail with a DataError saying what is wrong.
  const auto expect_load_refused = [&](const std::string& what, const std::string& message) {
    AtlasStore store = open_store(vocabulary.hash());
    Atlas broken;
    try {
      store.load_atlas(broken, &vocabulary);
      ADD_FAILURE() << what << " was loaded";
    } catch (const DataError& e) {
      EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << what << ": " << e.what();
    }
  };
  const std::unique_ptr<SqlConnection> raw = raw_connection();
  // The IMU in the camera stored in part: the error names the link.
  raw->exec("UPDATE keyframe_inertial_links SET c_i_tx = NULL WHERE keyframe_id = " + std::to_string(kfs[4]->id()));
  expect_load_refused("a link whose IMU-in-camera is stored in part", "IMU in the camera is stored in part");
  raw->exec("UPDATE keyframe_inertial_links SET c_i_tx = 0.02 WHERE keyframe_id = " + std::to_string(kfs[4]->id()));
  // A scale-factor correction that is not finite: the error names the map's state.
  raw->prepare_statement("UPDATE map_inertial_states SET say = ?1 WHERE map_id = ?2")
      ->bind_real(1, std::numeric_limits<double>::infinity())
      .bind_int64(2, static_cast<std::int64_t>(map->id()))
      .run();
  expect_load_refused("an infinite scale-factor correction", "inertial state is not finite");
  raw->exec("UPDATE map_inertial_states SET say = 0.0042 WHERE map_id = " + std::to_string(map->id()));
  // A corrupt increments blob: the error names the link.
  raw->prepare_statement("UPDATE keyframe_inertial_links SET increments = ?1 WHERE keyframe_id = ?2")
      ->bind_blob(1, std::string("\x00\x00\x80\x3f", 4))
      .bind_int64(2, static_cast<std::int64_t>(kfs[4]->id()))
      .run();
  expect_load_refused("a corrupt increments blob", "inertial link");
}

// Schema 18 added the IMU's scale-factor correction to map_inertial_states: a
// map stored before it loads with none, and keeps one written after the migration.
TEST(PersistenceInertialSchema, AMapOfSchemaSeventeenLoadsWithoutAScaleCorrection) {
  const Vocabulary& vocabulary = test_vocabulary();
  std::mt19937_64 rng(29);
  Atlas original;
  std::vector<std::shared_ptr<KeyFrame>> kfs;
  auto map = inertial_map(original, rng, vocabulary, kfs);
  TempDb db("v17_inertial");
  { AtlasStore::open(db.path(), vocabulary.hash()).save_atlas(original); }
  {
    SqliteDb raw(db.path());
    raw.exec(std::string("BEGIN; ") + kUndoSchema18Sqlite +
             "DELETE FROM schema_migrations WHERE version >= 18; PRAGMA user_version = 17; COMMIT");
  }
  AtlasStore store = AtlasStore::open(db.path(), vocabulary.hash());
  EXPECT_EQ(store.schema_version(), latest_schema_version());
  {
    Atlas loaded;
    store.load_atlas(loaded, &vocabulary);
    const auto state = loaded.map(map->id())->inertial_state();
    ASSERT_TRUE(state.has_value());
    EXPECT_EQ(state->scale, ImuScaleCorrection{});
    EXPECT_EQ(state->gravity_w, map->inertial_state()->gravity_w);
  }
  store.save_atlas(original);
  Atlas loaded;
  store.load_atlas(loaded, &vocabulary);
  expect_atlas_eq(original, loaded, true);
}

// A version-1 blob (written before the vibration was stored) reads with no
// vibration and the same measurements; version 2 keeps the vibration exactly.
TEST(IncrementsBlob, VersionOneReadsWithoutVibrationAndVersionTwoKeepsIt) {
  std::mt19937_64 rng(3);
  const auto pre = random_increments(rng, 40);
  const Preintegration again = decode_increments(encode_increments(*pre), "link 1");
  EXPECT_EQ(again.noise().vibration, pre->noise().vibration);
  EXPECT_EQ(again.covariance(), pre->covariance());
  EXPECT_GT((pre->covariance() - pre->white_covariance()).norm(), 0.0);

  std::vector<double> v = decode_doubles(encode_increments(*pre), "link 1");
  v[0] = 1.0;
  v.erase(v.begin() + 11, v.begin() + 17);  // the vibration's six values
  const Preintegration old = decode_increments(encode_doubles(v), "link 1");
  EXPECT_EQ(old.noise().vibration, ImuVibration{});
  EXPECT_EQ(old.delta_v(), pre->delta_v());
  EXPECT_EQ(old.covariance(), pre->white_covariance());

  v = decode_doubles(encode_increments(*pre), "link 1");
  v[14] = -1e-6;  // a negative velocity variance
  try {
    decode_increments(encode_doubles(v), "link 1");
    FAIL() << "a negative vibration variance was decoded";
  } catch (const DataError& e) {
    EXPECT_NE(std::string(e.what()).find("vibration variance"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace orbatlas
