#include "tests/persistence/test_persistence_expect.h"

#include <gtest/gtest.h>

#include <vector>

namespace orbatlas::test {

void expect_pose_eq(const Pose3& a, const Pose3& b, const std::string& what) {
  EXPECT_EQ(a.q.coeffs(), b.q.coeffs()) << what;
  EXPECT_EQ(a.t, b.t) << what;
}

void expect_keyframe_eq(const Map& map_a, const KeyFrame& a, const KeyFrame& b, bool same_bow) {
  const std::string what = "keyframe " + std::to_string(a.id());
  EXPECT_EQ(a.id(), b.id());
  EXPECT_EQ(a.map_id(), b.map_id()) << what;
  EXPECT_FALSE(b.is_bad()) << what;
  EXPECT_EQ(a.timestamp_ns(), b.timestamp_ns()) << what;
  expect_pose_eq(a.T_w_b(), b.T_w_b(), what + " T_w_b");
  expect_pose_eq(a.T_b_c(), b.T_b_c(), what + " T_b_c");
  // Features, every field.
  EXPECT_EQ(a.features().width, b.features().width) << what;
  EXPECT_EQ(a.features().height, b.features().height) << what;
  ASSERT_EQ(a.slot_count(), b.slot_count()) << what;
  for (std::size_t i = 0; i < a.slot_count(); ++i) {
    const Keypoint &ka = a.keypoint(i), &kb = b.keypoint(i);
    EXPECT_EQ(ka.uv, kb.uv) << what << " slot " << i;
    EXPECT_EQ(ka.level, kb.level) << what << " slot " << i;
    EXPECT_EQ(ka.angle_deg, kb.angle_deg) << what << " slot " << i;
    EXPECT_EQ(ka.response, kb.response) << what << " slot " << i;
    EXPECT_EQ(ka.bearing, kb.bearing) << what << " slot " << i;
    EXPECT_EQ(ka.uv_undistorted, kb.uv_undistorted) << what << " slot " << i;
    EXPECT_EQ(a.depth(i), b.depth(i)) << what << " slot " << i;
    EXPECT_EQ(a.u_right(i), b.u_right(i)) << what << " slot " << i;
  }
  EXPECT_EQ(a.features().descriptors, b.features().descriptors) << what;
  EXPECT_EQ(a.is_stereo(), b.is_stereo()) << what;
  EXPECT_EQ(a.has_depth(), b.has_depth()) << what;
  EXPECT_EQ(a.units(), b.units()) << what;
  if (same_bow) {
    EXPECT_EQ(a.bow(), b.bow()) << what;
    EXPECT_EQ(a.feature_vector(), b.feature_vector()) << what;
  } else {
    EXPECT_TRUE(b.bow().empty()) << what;
    EXPECT_TRUE(b.feature_vector().empty()) << what;
  }
  // The rebuilt grid answers like the original.
  EXPECT_EQ(a.grid().size(), b.grid().size()) << what;
  EXPECT_EQ(a.grid().cols(), b.grid().cols()) << what;
  EXPECT_EQ(a.grid().rows(), b.grid().rows()) << what;
  for (const Eigen::Vector2f& uv : {Eigen::Vector2f(100, 100), Eigen::Vector2f(400, 250), Eigen::Vector2f(700, 450)})
    EXPECT_EQ(a.grid().in_radius(uv, 60.0f), b.grid().in_radius(uv, 60.0f)) << what;
  // Observations and graph.
  const auto sa = a.slots(), sb = b.slots();
  for (std::size_t i = 0; i < sa.size(); ++i) {
    ASSERT_EQ(sa[i] == nullptr, sb[i] == nullptr) << what << " slot " << i;
    if (sa[i]) {
      EXPECT_EQ(sa[i]->id(), sb[i]->id()) << what << " slot " << i;
    }
  }
  EXPECT_EQ(a.map_point_count(), b.map_point_count()) << what;
  EXPECT_EQ(a.redundant_map_point_count(), b.redundant_map_point_count()) << what;
  // Links to culled keyframes are not stored: culling erases only the links the
  // culled keyframe itself holds, so a neighbour whose mirrored link it had
  // dropped keeps a dead one (as in ORB-SLAM); it is not worth persisting.
  std::vector<CovisibilityEdge> ca;
  for (const CovisibilityEdge& edge : a.connections())
    if (map_a.keyframe(edge.keyframe)) ca.push_back(edge);
  const auto cb = b.connections();
  ASSERT_EQ(ca.size(), cb.size()) << what;
  for (std::size_t i = 0; i < ca.size(); ++i) {
    EXPECT_EQ(ca[i].keyframe, cb[i].keyframe) << what << " connection " << i;
    EXPECT_EQ(ca[i].weight, cb[i].weight) << what << " connection " << i;
  }
  EXPECT_EQ(a.parent_id(), b.parent_id()) << what;
  EXPECT_EQ(a.child_ids(), b.child_ids()) << what;
  EXPECT_EQ(a.loop_edge_ids(), b.loop_edge_ids()) << what;
}

void expect_point_eq(const MapPoint& a, const MapPoint& b) {
  const std::string what = "map point " + std::to_string(a.id());
  EXPECT_EQ(a.id(), b.id());
  EXPECT_EQ(a.map_id(), b.map_id()) << what;
  EXPECT_EQ(a.p_w(), b.p_w()) << what;
  EXPECT_EQ(a.normal(), b.normal()) << what;
  EXPECT_EQ(a.min_distance(), b.min_distance()) << what;
  EXPECT_EQ(a.max_distance(), b.max_distance()) << what;
  EXPECT_EQ(a.descriptor(), b.descriptor()) << what;
  EXPECT_EQ(a.reference_keyframe_id(), b.reference_keyframe_id()) << what;
  EXPECT_EQ(a.visible(), b.visible()) << what;
  EXPECT_EQ(a.found(), b.found()) << what;
  const auto oa = a.observations(), ob = b.observations();
  ASSERT_EQ(oa.size(), ob.size()) << what;
  for (std::size_t i = 0; i < oa.size(); ++i) {
    EXPECT_EQ(oa[i].keyframe, ob[i].keyframe) << what;
    EXPECT_EQ(oa[i].slot, ob[i].slot) << what;
    EXPECT_EQ(oa[i].level, ob[i].level) << what;
  }
}

void expect_culled_eq(const Map& a, const Map& b) {
  const auto ca = a.culled_keyframes(), cb = b.culled_keyframes();
  ASSERT_EQ(ca.size(), cb.size()) << "map " << a.id();
  for (std::size_t i = 0; i < ca.size(); ++i) {
    const std::string what = "culled keyframe " + std::to_string(ca[i].id);
    ASSERT_EQ(ca[i].id, cb[i].id) << what;
    EXPECT_EQ(ca[i].parent, cb[i].parent) << what;
    expect_pose_eq(ca[i].T_parent_b, cb[i].T_parent_b, what + " T_parent_b");
    EXPECT_EQ(ca[i].units, cb[i].units) << what;
    // What trajectories anchored to it resolve to: chained through the same
    // (possibly culled) parents to the same alive keyframe.
    const auto pa = a.keyframe_pose(ca[i].id), pb = b.keyframe_pose(cb[i].id);
    ASSERT_TRUE(pa.has_value()) << what;
    ASSERT_TRUE(pb.has_value()) << what;
    expect_pose_eq(*pa, *pb, what + " keyframe_pose");
  }
}

void expect_inertial_eq(const Map& a, const Map& b) {
  const auto sa = a.inertial_state(), sb = b.inertial_state();
  ASSERT_EQ(sa.has_value(), sb.has_value()) << "map " << a.id() << " inertial state";
  if (sa) {
    EXPECT_EQ(sa->initialized_at_ns, sb->initialized_at_ns);
    EXPECT_EQ(sa->gravity_w, sb->gravity_w);
    EXPECT_EQ(sa->bias, sb->bias);
    EXPECT_EQ(sa->keyframes, sb->keyframes);
    EXPECT_EQ(sa->span_s, sb->span_s);
    EXPECT_EQ(sa->refinements, sb->refinements);
    EXPECT_EQ(sa->scale, sb->scale);
  }
  const auto ka = a.keyframes(), kb = b.keyframes();
  ASSERT_EQ(ka.size(), kb.size());
  for (std::size_t i = 0; i < ka.size(); ++i) {
    const auto ia = ka[i]->imu_state(), ib = kb[i]->imu_state();
    ASSERT_EQ(ia.has_value(), ib.has_value()) << "keyframe " << ka[i]->id() << " IMU state";
    if (ia) {
      EXPECT_EQ(ia->v_i, ib->v_i) << "keyframe " << ka[i]->id() << " velocity";
      EXPECT_EQ(ia->bias, ib->bias) << "keyframe " << ka[i]->id() << " biases";
    }
    const std::string what = "keyframe " + std::to_string(ka[i]->id()) + " inertial link";
    const auto la = ka[i]->inertial_link(), lb = kb[i]->inertial_link();
    ASSERT_EQ(la.has_value(), lb.has_value()) << what;
    if (!la) continue;
    EXPECT_EQ(la->previous_id, lb->previous_id) << what;
    ASSERT_EQ(la->T_c_i.has_value(), lb->T_c_i.has_value()) << what << " IMU in the camera";
    if (la->T_c_i) {
      EXPECT_EQ(la->T_c_i->t, lb->T_c_i->t) << what << " IMU in the camera";
      EXPECT_EQ(la->T_c_i->q.coeffs(), lb->T_c_i->q.coeffs()) << what << " IMU in the camera";
    }
    const Preintegration &pa = *la->from_previous, &pb = *lb->from_previous;
    // Integrated again from the stored measurements: bit for bit.
    EXPECT_EQ(pa.measurements().size(), pb.measurements().size()) << what;
    EXPECT_EQ(pa.dt(), pb.dt()) << what;
    EXPECT_EQ(pa.bias(), pb.bias()) << what;
    EXPECT_EQ(pa.delta_R(), pb.delta_R()) << what;
    EXPECT_EQ(pa.delta_v(), pb.delta_v()) << what;
    EXPECT_EQ(pa.delta_p(), pb.delta_p()) << what;
    EXPECT_EQ(pa.covariance(), pb.covariance()) << what;
    EXPECT_EQ(pa.dp_dba(), pb.dp_dba()) << what;
    EXPECT_EQ(pa.dR_dbg(), pb.dR_dbg()) << what;
  }
}

void expect_map_eq(const Map& a, const Map& b, bool same_bow) {
  ASSERT_EQ(a.id(), b.id());
  const auto ka = a.keyframes(), kb = b.keyframes();
  ASSERT_EQ(ka.size(), kb.size()) << "map " << a.id();
  for (std::size_t i = 0; i < ka.size(); ++i) expect_keyframe_eq(a, *ka[i], *kb[i], same_bow);
  const auto pa = a.map_points(), pb = b.map_points();
  ASSERT_EQ(pa.size(), pb.size()) << "map " << a.id();
  for (std::size_t i = 0; i < pa.size(); ++i) expect_point_eq(*pa[i], *pb[i]);
  expect_culled_eq(a, b);
  expect_inertial_eq(a, b);
}

void expect_atlas_eq(const Atlas& a, const Atlas& b, bool same_bow) {
  const auto ma = a.maps(), mb = b.maps();
  ASSERT_EQ(ma.size(), mb.size());
  ASSERT_EQ(a.active_map() == nullptr, b.active_map() == nullptr);
  if (a.active_map()) {
    EXPECT_EQ(a.active_map()->id(), b.active_map()->id());
  }
  for (std::size_t m = 0; m < ma.size(); ++m) {
    expect_map_eq(*ma[m], *mb[m], same_bow);
    if (::testing::Test::HasFatalFailure()) return;
  }
  for (const IdKind kind : {IdKind::keyframe, IdKind::map_point, IdKind::map})
    EXPECT_EQ(a.ids().peek(kind), b.ids().peek(kind)) << "id kind " << static_cast<int>(kind);
}

std::size_t count_keyframes(const Atlas& atlas) {
  std::size_t n = 0;
  for (const auto& m : atlas.maps()) n += m->keyframe_count();
  return n;
}

std::size_t count_points(const Atlas& atlas) {
  std::size_t n = 0;
  for (const auto& m : atlas.maps()) n += m->map_point_count();
  return n;
}

std::size_t count_culled_keyframes(const Atlas& atlas) {
  std::size_t n = 0;
  for (const auto& m : atlas.maps()) n += m->culled_keyframes().size();
  return n;
}

}  // namespace orbatlas::test
