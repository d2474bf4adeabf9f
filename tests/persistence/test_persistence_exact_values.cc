// Values come back from either database exactly: doubles bit for
// bit (subnormals, extremes, infinities, random mantissas), blobs byte for
// byte, 64-bit integers at both ends of their range, text with quotes and
// UTF-8. One difference is pinned down: SQLite stores a REAL -0.0 as +0.0
// (it keeps integral reals as integers), PostgreSQL keeps its sign.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "core/persistence/atlas_store.h"
#include "tests/support/persistence_backends.h"
#include "tests/persistence/test_persistence_random_atlas.h"

namespace orbatlas {
namespace {

using namespace test;  // NOLINT: the shared helpers of the persistence tests
using Limits = std::numeric_limits<double>;

std::uint64_t bits(double value) {
  std::uint64_t b;
  std::memcpy(&b, &value, sizeof b);
  return b;
}

void expect_bits_eq(double stored, double loaded, const std::string& what) {
  EXPECT_EQ(bits(stored), bits(loaded)) << what << ": stored " << stored << ", loaded " << loaded;
}

void expect_pose_bits_eq(const Pose3& a, const Pose3& b, const std::string& what) {
  for (int i = 0; i < 4; ++i) expect_bits_eq(a.q.coeffs()[i], b.q.coeffs()[i], what + " q[" + std::to_string(i) + "]");
  for (int i = 0; i < 3; ++i) expect_bits_eq(a.t[i], b.t[i], what + " t[" + std::to_string(i) + "]");
}

// A unit quaternion with full random mantissas, stored as it is (never renormalised).
Pose3 pose_with_translation(std::mt19937_64& rng, const Eigen::Vector3d& t) {
  Pose3 pose = random_pose(rng);
  pose.t = t;
  return pose;
}

using PersistenceExactValues = AtlasBackendTest;
ORBATLAS_PERSISTENCE_BACKENDS(PersistenceExactValues);

TEST_P(PersistenceExactValues, DoublesBlobsIntegersAndTextRoundTripExactly) {
  AtlasStore store = open_store(test_vocabulary().hash());
  std::mt19937_64 rng(41);

  SessionInfo session;
  session.id = static_cast<SessionId>(std::numeric_limits<std::int64_t>::max());  // the largest id stored
  session.name = "grüße, 'quoted' \"and\" ?1 ? $1 \\ ;";
  session.sensor = SensorType::kStereoInertial;
  session.created_ns = std::numeric_limits<std::int64_t>::min();
  CameraCalibration c;
  c.model = CameraModel::kPinholeRadTan;
  c.fx = Limits::denorm_min();  // > 0, as the schema asks
  c.fy = Limits::max();
  c.cx = -Limits::infinity();
  c.cy = std::nextafter(1.0, 2.0);
  // The distortion blob keeps every bit, -0.0 and NaN payloads included.
  c.distortion = {-0.0, Limits::denorm_min(), -Limits::max(), Limits::quiet_NaN(), 0.1};
  c.width = std::numeric_limits<int>::max();
  c.height = 1;
  c.rate_hz = Limits::min();  // the smallest normal
  c.T_b_c = pose_with_translation(rng, {Limits::lowest(), -Limits::denorm_min(), Limits::infinity()});
  session.cameras = {c};
  store.save_session(session);

  const std::vector<FrameAnchor> anchors = {
      {std::numeric_limits<std::int64_t>::min(), 0, 0, pose_with_translation(rng, {1e-310, -1e300, M_PI})},
      {-1, static_cast<MapId>(std::numeric_limits<std::int64_t>::max()), 7,
       pose_with_translation(rng, {std::nextafter(0.0, 1.0), std::nextafter(1.0, 0.0), -2.5e-320})},
      {std::numeric_limits<std::int64_t>::max(), 3, static_cast<KeyframeId>(std::numeric_limits<std::int64_t>::max()),
       pose_with_translation(rng, {0.0, 1.0, -1.0})},
  };
  store.save_trajectory(session.id, anchors);

  AtlasStore reopened = open_store(test_vocabulary().hash());
  const auto loaded = reopened.load_session(session.id);
  ASSERT_TRUE(loaded.has_value());
  EXPECT_EQ(loaded->id, session.id);
  EXPECT_EQ(loaded->name, session.name);
  EXPECT_EQ(loaded->sensor, session.sensor);
  EXPECT_EQ(loaded->created_ns, session.created_ns);
  ASSERT_EQ(loaded->cameras.size(), 1u);
  const CameraCalibration& l = loaded->cameras[0];
  expect_bits_eq(c.fx, l.fx, "fx");
  expect_bits_eq(c.fy, l.fy, "fy");
  expect_bits_eq(c.cx, l.cx, "cx");
  expect_bits_eq(c.cy, l.cy, "cy");
  expect_bits_eq(c.rate_hz, l.rate_hz, "rate_hz");
  ASSERT_EQ(l.distortion.size(), c.distortion.size());
  for (std::size_t i = 0; i < c.distortion.size(); ++i)
    expect_bits_eq(c.distortion[i], l.distortion[i], "distortion " + std::to_string(i));
  EXPECT_EQ(l.width, c.width);
  expect_pose_bits_eq(c.T_b_c, l.T_b_c, "T_b_c");

  const std::vector<FrameAnchor> back = reopened.load_trajectory(session.id);
  ASSERT_EQ(back.size(), anchors.size());
  for (std::size_t i = 0; i < anchors.size(); ++i) {
    EXPECT_EQ(back[i].t_ns, anchors[i].t_ns);
    EXPECT_EQ(back[i].map, anchors[i].map);
    EXPECT_EQ(back[i].reference, anchors[i].reference);
    expect_pose_bits_eq(anchors[i].T_ref_b, back[i].T_ref_b, "anchor " + std::to_string(i));
  }

  // -0.0 in a REAL / double precision column: equal on both, its sign kept only by PostgreSQL.
  const FrameAnchor negative_zero{5, 0, 0, pose_with_translation(rng, {-0.0, 0.0, 1.0})};
  reopened.save_trajectory(session.id, {negative_zero});
  const std::vector<FrameAnchor> zero = reopened.load_trajectory(session.id);
  ASSERT_EQ(zero.size(), 1u);
  EXPECT_EQ(zero[0].T_ref_b.t.x(), 0.0);
  EXPECT_EQ(std::signbit(zero[0].T_ref_b.t.x()), backend() == SqlDialect::kPostgres);
}

}  // namespace
}  // namespace orbatlas
