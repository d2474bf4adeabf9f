// Mapping and tracking building blocks against exact synthetic scenes:
// triangulation, fusion of duplicates, keyframe culling with both schemes,
// projection and bag-of-words search, poses of culled keyframes, the bounded
// queue, percentiles. Local mapping itself is in test_local_mapping.cc.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <map>
#include <thread>

#include "core/common/bounded_queue.h"
#include "core/map/atlas.h"
#include "core/map/map_point_update.h"
#include "core/mapping/fusion.h"
#include "core/mapping/keyframe_culling.h"
#include "core/mapping/triangulation.h"
#include "core/slam/slam_stats.h"
#include "core/tracking/frame_pose.h"
#include "core/tracking/projection_search.h"
#include "tests/support/mapping_scene.h"

namespace orbatlas {
namespace {

using test::at;
using test::keyframe_data;
using test::make_scene;
using test::observe;
using test::Scene;

TEST(Triangulation, DltRecoversAnExactPoint) {
  const Pose3 T_c1_w = at(0, 0, 0), T_c2_w = Pose3(Eigen::Quaterniond(Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitY())),
                                                   Eigen::Vector3d(-0.4, 0.05, 0.1));
  const Eigen::Vector3d p(0.7, -0.3, 4.2);
  const Eigen::Vector3d p1 = T_c1_w * p, p2 = T_c2_w * p;
  Eigen::Vector3d out;
  ASSERT_TRUE(triangulate_dlt(p1.head<2>() / p1.z(), p2.head<2>() / p2.z(), T_c1_w, T_c2_w, &out));
  EXPECT_LT((out - p).norm(), 1e-9);
}

TEST(Triangulation, NewPointsBetweenTwoKeyframesLandOnTheTruePoints) {
  const Scene s = make_scene(300);
  Atlas atlas;
  auto map = atlas.create_map();
  std::vector<std::size_t> idx1, idx2;
  auto kf1 = map->new_keyframe(keyframe_data(s, at(0, 0, 0), &idx1));
  auto kf2 = map->new_keyframe(keyframe_data(s, at(0.5, 0.05, 0.1), &idx2));
  std::vector<std::shared_ptr<MapPoint>> created;
  const TriangulationStats st = triangulate_pair(*map, kf1, kf2, s.cam(), &created);
  EXPECT_GE(st.created, static_cast<int>(std::min(idx1.size(), idx2.size()) * 9 / 10));
  EXPECT_EQ(map->map_point_count(), static_cast<std::size_t>(st.created));
  for (const auto& mp : created) {
    ASSERT_EQ(mp->observation_count(), 2u);
    const std::size_t slot = *mp->slot_in(kf1->id());
    EXPECT_LT((mp->p_w() - s.points[idx1[slot]]).norm(), 2e-5);  // keypoints are float pixels (~1e-5 px)
    EXPECT_EQ(idx2[*mp->slot_in(kf2->id())], idx1[slot]);        // the same scene point in both
    EXPECT_GT(mp->max_distance(), mp->min_distance());
  }
  // A second pass finds nothing new: every matched keypoint now has its point.
  EXPECT_EQ(triangulate_pair(*map, kf1, kf2, s.cam(), nullptr).created, 0);
}

TEST(Fusion, DuplicatePointsAreMergedAndMissingObservationsAdded) {
  const Scene s = make_scene(100);
  Atlas atlas;
  auto map = atlas.create_map();
  std::vector<std::size_t> idx1, idx2;
  auto kf1 = map->new_keyframe(keyframe_data(s, at(0, 0, 0), &idx1));
  auto kf2 = map->new_keyframe(keyframe_data(s, at(0.3, 0, 0), &idx2));
  ASSERT_GE(idx1.size(), 20u);
  auto slot_of = [](const std::vector<std::size_t>& idx, std::size_t point) {
    return static_cast<std::size_t>(std::find(idx.begin(), idx.end(), point) - idx.begin());
  };
  // Point A seen by kf1 only; its duplicate B (same place and descriptor) by kf2 only.
  const std::size_t pa = idx1[0];
  ASSERT_LT(slot_of(idx2, pa), idx2.size());
  auto make_point = [&](const std::shared_ptr<KeyFrame>& kf, std::size_t slot, std::size_t point) {
    MapPointData d;
    d.p_w = s.points[point];
    d.descriptor = s.descriptors[point];
    auto mp = map->new_map_point(d);
    kf->add_observation(slot, mp);
    update_map_point(*mp, ScalePyramid{});
    return mp;
  };
  auto a = make_point(kf1, 0, pa);
  auto b = make_point(kf2, slot_of(idx2, pa), pa);
  // Point C seen by kf2 only, at a keypoint kf1 has free.
  const std::size_t pc = idx1[1];
  ASSERT_LT(slot_of(idx2, pc), idx2.size());
  auto c = make_point(kf2, slot_of(idx2, pc), pc);
  ASSERT_EQ(map->map_point_count(), 3u);

  const FusionStats st = fuse_into_keyframe(*map, kf1, {b, c}, s.cam());
  EXPECT_EQ(st.merged, 1);
  EXPECT_EQ(st.added, 1);
  EXPECT_EQ(map->map_point_count(), 2u);
  EXPECT_TRUE(a->is_bad() != b->is_bad());
  const auto survivor = a->is_bad() ? b : a;
  EXPECT_EQ(kf1->map_point(0), survivor);
  EXPECT_EQ(kf2->map_point(slot_of(idx2, pa)), survivor);
  EXPECT_EQ(survivor->observation_count(), 2u);
  EXPECT_EQ(kf1->map_point(1), c);
  EXPECT_EQ(atlas.counters()->map_points().culled, 1u);
}

TEST(KeyframeCulling, BothSchemesCullTheSameRedundantKeyframes) {
  for (const CullingScheme scheme : {CullingScheme::kScan, CullingScheme::kIncremental}) {
    const Scene s = make_scene(60);
    Atlas atlas;
    auto map = atlas.create_map();
    std::vector<std::shared_ptr<KeyFrame>> kfs;
    std::vector<std::vector<std::size_t>> idx(5);
    for (int k = 0; k < 5; ++k) kfs.push_back(map->new_keyframe(keyframe_data(s, at(0.02 * k, 0, 0), &idx[k])));
    // Every keyframe observes every point it sees (the same 60 points, all at level 0).
    std::map<std::size_t, std::shared_ptr<MapPoint>> points;
    for (int k = 0; k < 5; ++k) {
      for (std::size_t slot = 0; slot < idx[k].size(); ++slot) {
        auto& mp = points[idx[k][slot]];
        if (!mp) mp = map->new_map_point({s.points[idx[k][slot]], s.descriptors[idx[k][slot]]});
        kfs[k]->add_observation(slot, mp);
      }
    }
    for (auto& kf : kfs) kf->update_connections();
    KeyframeCullingOptions o;
    o.scheme = scheme;
    o.compare_schemes = true;
    const auto r = cull_redundant_keyframes(*map, *kfs[4], kfs[0]->id(), o);
    // kf1: every point seen by 4 others; then kf2 by 3 others (0, 3, 4); then kf3 by only 2.
    EXPECT_EQ(r.culled, (std::vector<KeyframeId>{kfs[1]->id(), kfs[2]->id()})) << culling_scheme_name(scheme);
    EXPECT_EQ(r.candidates, 3);  // the origin is never a candidate
    EXPECT_EQ(r.disagreements, 0);
    EXPECT_EQ(map->keyframe_count(), 3u);
  }
}

TEST(ProjectionSearch, ProjectedPointsFindTheirKeypoints) {
  const Scene s = make_scene(300);
  Atlas atlas;
  auto map = atlas.create_map();
  std::vector<std::size_t> idx_kf, idx_frame;
  auto kf = map->new_keyframe(keyframe_data(s, at(0, 0, 0), &idx_kf));
  for (std::size_t slot = 0; slot < idx_kf.size(); ++slot) {
    auto mp = map->new_map_point({s.points[idx_kf[slot]], s.descriptors[idx_kf[slot]]});
    kf->add_observation(slot, mp);
    update_map_point(*mp, ScalePyramid{});
  }
  const Pose3 T_w_c =
      Pose3(Eigen::Quaterniond(Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitY())), Eigen::Vector3d(0.2, 0, 0.1));
  Frame frame;
  frame.features = observe(s, T_w_c, &idx_frame);
  frame.grid = FeatureGrid(frame.features);
  frame.depth.assign(frame.size(), -1.0f);
  frame.u_right.assign(frame.size(), -1.0f);
  frame.map_points.assign(frame.size(), nullptr);
  frame.outlier.assign(frame.size(), false);

  // By projection with the true pose.
  std::vector<ProjectedPoint> projected;
  for (const auto& mp : kf->map_points()) {
    ProjectedPoint pp;
    if (project_into_frame(*mp, T_w_c.inverse(), s.cam(), &pp)) {
      pp.point = mp;
      projected.push_back(pp);
    }
  }
  const int found = search_projected_points(frame, projected, s.cam(), 1.0f);
  EXPECT_GE(found, static_cast<int>(projected.size() * 95 / 100));
  int correct = 0;
  for (std::size_t i = 0; i < frame.size(); ++i) {
    if (!frame.map_points[i]) continue;
    const std::size_t slot = *frame.map_points[i]->slot_in(kf->id());
    EXPECT_EQ(idx_kf[slot], idx_frame[i]);
    ++correct;
  }
  EXPECT_EQ(correct, found);

  // Pose-only optimisation from a perturbed pose lands on the truth.
  frame.T_w_b = T_w_c * at(0.03, -0.02, 0.05);
  EXPECT_GE(optimize_frame_pose(frame, s.cam(), Pose3()), found - 2);
  EXPECT_LT(translation_distance(frame.T_w_b, T_w_c), 1e-6);

  // By bag of words (one node holds everything): the same associations.
  std::fill(frame.map_points.begin(), frame.map_points.end(), nullptr);
  for (std::uint32_t i = 0; i < frame.size(); ++i) frame.feature_vector[0].push_back(i);
  const int bow = search_by_bow(*kf, frame);
  EXPECT_GE(bow, static_cast<int>(projected.size() * 95 / 100));
  for (std::size_t i = 0; i < frame.size(); ++i) {
    if (frame.map_points[i]) {
      EXPECT_EQ(idx_kf[*frame.map_points[i]->slot_in(kf->id())], idx_frame[i]);
    }
  }
}

TEST(MapModel, CulledKeyframePoseFollowsItsParent) {
  Atlas atlas;
  auto map = atlas.create_map();
  KeyFrameData d;
  d.features.keypoints.resize(1);
  d.T_w_b = at(1, 0, 0);
  auto root = map->new_keyframe(d);
  d.T_w_b = at(1, 2, 0);
  auto child = map->new_keyframe(d);
  child->set_parent(root);
  const KeyframeId child_id = child->id();
  ASSERT_TRUE(map->cull_keyframe(child_id));
  child.reset();
  EXPECT_EQ(atlas.counters()->keyframes().reclaimed, 1u);  // freed, yet its pose can be resolved
  root->set_T_w_b(at(5, 0, 0));
  const auto pose = map->keyframe_pose(child_id);
  ASSERT_TRUE(pose.has_value());
  EXPECT_LT((pose->t - Eigen::Vector3d(5, 2, 0)).norm(), 1e-12);
  EXPECT_FALSE(map->keyframe_pose(9999).has_value());
}

TEST(BoundedQueue, BlocksWhenFullAndDrainsAfterClose) {
  BoundedQueue<int> q(2);
  EXPECT_TRUE(q.push(1));
  EXPECT_TRUE(q.push(2));
  std::atomic<bool> third_pushed{false};
  std::thread producer([&] {
    q.push(3);
    third_pushed = true;
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_FALSE(third_pushed.load());  // blocked: the queue is full
  EXPECT_EQ(q.pop(), 1);
  producer.join();
  EXPECT_TRUE(third_pushed.load());
  EXPECT_EQ(q.size(), 2u);
  q.close();
  EXPECT_FALSE(q.push(4));
  EXPECT_EQ(q.pop(), 2);
  EXPECT_EQ(q.pop(), 3);
  EXPECT_FALSE(q.pop().has_value());
  EXPECT_THROW(BoundedQueue<int>(0), Error);
}

TEST(SlamStats, PercentilesOfKnownValues) {
  std::vector<double> v;
  for (int i = 100; i >= 0; --i) v.push_back(i);
  const Percentiles p = percentiles(v);
  EXPECT_DOUBLE_EQ(p.p50, 50.0);
  EXPECT_DOUBLE_EQ(p.p95, 95.0);
  EXPECT_DOUBLE_EQ(p.p99, 99.0);
  EXPECT_DOUBLE_EQ(p.max, 100.0);
  EXPECT_DOUBLE_EQ(p.mean, 50.0);
  EXPECT_EQ(percentiles(std::vector<double>{}).count, 0u);
}

// Bounded summaries: exact while the values fit the sample; beyond it count,
// mean and max stay exact and the percentiles are those of a uniform sample.
TEST(SlamStats, SampleSummaryIsExactThenBounded) {
  SampleSummary small(256);
  for (int i = 100; i >= 0; --i) small.add(i);
  const Percentiles p = small.percentiles();
  EXPECT_DOUBLE_EQ(p.p50, 50.0);
  EXPECT_DOUBLE_EQ(p.p95, 95.0);
  EXPECT_EQ(p.count, 101u);
  SampleSummary big(512);
  for (int i = 0; i < 200000; ++i) big.add(static_cast<double>(i % 1000));  // uniform on 0..999
  const Percentiles q = big.percentiles();
  EXPECT_EQ(big.sample().size(), 512u);
  EXPECT_EQ(q.count, 200000u);
  EXPECT_DOUBLE_EQ(q.max, 999.0);
  EXPECT_DOUBLE_EQ(q.mean, 499.5);
  EXPECT_NEAR(q.p50, 500.0, 60.0);  // a 512-value sample: within a few percent
  EXPECT_NEAR(q.p95, 950.0, 30.0);
}

}  // namespace
}  // namespace orbatlas
