// Map model: a map's frame changed (gravity alignment) and its scale changed
// (made metric), when a map is metric, and frame anchors following their
// keyframes' units through culled parents.
#include <gtest/gtest.h>

#include <cmath>

#include "core/common/error.h"
#include "core/map/atlas.h"
#include "tests/support/map_keyframes.h"

namespace orbatlas {
namespace {

using test::keyframe_data;

// Changing a map's frame (the gravity alignment of a visual-inertial map):
// every keyframe, point and viewing direction follows, the relative geometry is
// kept, and the frame epoch moves on (a global BA solved before is dropped).
TEST(MapModel, ChangingTheFrameMovesEverythingAndKeepsTheGeometry) {
  Atlas atlas;
  auto map = atlas.create_map();
  auto a = map->new_keyframe(keyframe_data(1));
  auto b = map->new_keyframe(keyframe_data(1));
  a->set_T_w_b(Pose3(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ())), Eigen::Vector3d(1, 2, 3)));
  b->set_T_w_b(Pose3(Eigen::Quaterniond(Eigen::AngleAxisd(-0.2, Eigen::Vector3d::UnitX())), Eigen::Vector3d(0, 1, 0)));
  MapPointData d;
  d.p_w = Eigen::Vector3d(4, 5, 6);
  auto p = map->new_map_point(d);
  p->set_normal(Eigen::Vector3d(0, 0, 1));
  const Pose3 relative = a->T_w_b().inverse() * b->T_w_b();
  const Pose3 T(Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 1, 0).normalized())),
                Eigen::Vector3d::Zero());
  const auto epoch = map->frame_epoch();
  map->change_frame(T);
  EXPECT_EQ(map->frame_epoch(), epoch + 1);
  EXPECT_LT((p->p_w() - T * Eigen::Vector3d(4, 5, 6)).norm(), 1e-12);
  EXPECT_LT((p->normal() - T.q * Eigen::Vector3d(0, 0, 1)).norm(), 1e-12);
  const Pose3 after = a->T_w_b().inverse() * b->T_w_b();
  EXPECT_LT((after.t - relative.t).norm(), 1e-12);
  EXPECT_LT(after.q.angularDistance(relative.q), 1e-12);
}

// Rescaling a map (a monocular map made metric by its IMU): positions, point
// distances, IMU velocities and culled keyframes' anchors scale; rotations and
// viewing directions stay; the keyframes' units accumulate and the epoch moves on.
TEST(MapModel, RescalingScalesPositionsDistancesVelocitiesAndAnchors) {
  Atlas atlas;
  auto map = atlas.create_map();
  auto a = map->new_keyframe(keyframe_data(1));
  auto b = map->new_keyframe(keyframe_data(1));
  auto c = map->new_keyframe(keyframe_data(1));
  const Eigen::Quaterniond qa(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()));
  a->set_T_w_b(Pose3(qa, Eigen::Vector3d(1, 2, 3)));
  b->set_T_w_b(Pose3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 1, 0)));
  c->set_T_w_b(Pose3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 2, 0)));
  c->set_parent(b);
  a->set_imu_state(KeyFrame::ImuState{Eigen::Vector3d(0.1, 0.2, 0.3), {}});
  MapPointData d;
  d.p_w = Eigen::Vector3d(4, 5, 6);
  auto p = map->new_map_point(d);
  p->set_normal(Eigen::Vector3d(0, 0, 1));
  p->set_distances(1.0f, 8.0f);
  ASSERT_TRUE(map->cull_keyframe(c->id()));  // anchored to b: 1 m along y
  const auto epoch = map->frame_epoch();
  map->rescale(2.5);
  map->rescale(2.0);
  EXPECT_DOUBLE_EQ(a->units(), 5.0);
  EXPECT_DOUBLE_EQ(map->keyframe_placement(c->id())->units, 5.0);  // culled: through b
  EXPECT_EQ(map->frame_epoch(), epoch + 2);
  EXPECT_LT((a->T_w_b().t - Eigen::Vector3d(5, 10, 15)).norm(), 1e-12);
  EXPECT_LT(a->T_w_b().q.angularDistance(qa), 1e-12);
  EXPECT_LT((a->imu_state()->v_i - Eigen::Vector3d(0.5, 1.0, 1.5)).norm(), 1e-12);
  EXPECT_LT((p->p_w() - Eigen::Vector3d(20, 25, 30)).norm(), 1e-12);
  EXPECT_LT((p->normal() - Eigen::Vector3d(0, 0, 1)).norm(), 1e-12);
  EXPECT_FLOAT_EQ(p->min_distance(), 5.0f);
  EXPECT_FLOAT_EQ(p->max_distance(), 40.0f);
  const auto culled = map->keyframe_pose(c->id());
  ASSERT_TRUE(culled.has_value());
  EXPECT_LT((culled->t - Eigen::Vector3d(0, 10, 0)).norm(), 1e-12);  // b at 5, and 5 m on
  EXPECT_THROW(map->rescale(0.0), Error);
  EXPECT_THROW(map->rescale(std::nan("")), Error);
}

// A map is metric once it holds a keyframe with measured depths (stereo,
// RGB-D) or is inertial; monocular keyframes (depths all -1) leave it free.
TEST(MapModel, AMapIsMetricWithAKeyframeOfMeasuredDepthOrAnImu) {
  Atlas atlas;
  auto map = atlas.create_map();
  EXPECT_FALSE(map->metric_scale());  // empty
  KeyFrameData mono = keyframe_data(3);
  mono.depth.assign(3, -1.0f);
  mono.u_right.assign(3, -1.0f);
  EXPECT_FALSE(map->new_keyframe(mono)->has_depth());
  EXPECT_FALSE(map->metric_scale());
  map->set_inertial_state(Map::InertialState{});
  EXPECT_TRUE(map->metric_scale());

  auto stereo_map = atlas.create_map();
  map->new_keyframe(keyframe_data(2));  // no stereo vectors at all
  KeyFrameData stereo = mono;
  stereo.depth[1] = 2.5f;
  stereo.u_right[1] = 300.0f;
  const auto kf = stereo_map->new_keyframe(stereo);
  EXPECT_TRUE(kf->has_depth());
  EXPECT_TRUE(stereo_map->metric_scale());
}

// Frame anchors are stored in their keyframe's units, culled anchors in their
// parent's: a later change of scale about a keyframe (a Sim(3) loop moving
// it, a rescale of the map) moves and scales what hangs from it, exactly.
TEST(MapModel, AnchorsFollowTheirKeyframesUnitsThroughCulledParents) {
  Atlas atlas;
  auto map = atlas.create_map();
  auto a = map->new_keyframe(keyframe_data(1));
  auto b = map->new_keyframe(keyframe_data(1));
  a->set_T_w_b(Pose3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(1, 0, 0)));
  b->set_T_w_b(Pose3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(1, 2, 0)));
  b->set_parent(a);
  b->scale_units(2.0);  // b's neighbourhood was scaled once already
  // A frame 4 along z from b, stored as tracking stores it: divided by b's units.
  const FrameAnchor frame{1, map->id(), b->id(), Pose3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, 2))};
  const auto at = [&] { return atlas.frame_pose(frame).value().t; };
  EXPECT_LT((at() - Eigen::Vector3d(1, 2, 4)).norm(), 1e-12);
  ASSERT_TRUE(map->cull_keyframe(b->id()));
  EXPECT_LT((at() - Eigen::Vector3d(1, 2, 4)).norm(), 1e-12);  // through a now
  EXPECT_DOUBLE_EQ(map->keyframe_placement(b->id())->units, 2.0);

  // A Sim(3) correction about a: moved to the origin, lengths about it x3.
  a->set_T_w_b(Pose3());
  a->scale_units(3.0);
  EXPECT_LT((map->keyframe_pose(b->id())->t - Eigen::Vector3d(0, 6, 0)).norm(), 1e-12);
  EXPECT_DOUBLE_EQ(map->keyframe_placement(b->id())->units, 6.0);
  EXPECT_LT((at() - Eigen::Vector3d(0, 6, 12)).norm(), 1e-12);
  // The whole map halved.
  map->rescale(0.5);
  EXPECT_LT((at() - Eigen::Vector3d(0, 3, 6)).norm(), 1e-12);
  EXPECT_THROW(a->scale_units(0.0), Error);
  EXPECT_THROW(a->set_units(-1.0), Error);
}

}  // namespace
}  // namespace orbatlas
