// Mapping and tracking building blocks against exact synthetic scenes:
// triangulation, fusion of duplicates, keyframe culling with both schemes,
// projection and bag-of-words search, poses of culled keyframes, the bounded queue.
#include <gtest/gtest.h>

#include <chrono>
#include <future>
#include <random>
#include <thread>

#include "core/camera/camera_factory.h"
#include "core/common/bounded_queue.h"
#include "core/features/keypoint_geometry.h"
#include "core/map/atlas.h"
#include "core/map/map_point_update.h"
#include "core/mapping/fusion.h"
#include "core/mapping/local_mapper.h"
#include "core/slam/mapping_workers.h"
#include "core/mapping/keyframe_culling.h"
#include "core/mapping/triangulation.h"
#include "core/slam/slam_stats.h"
#include "core/tracking/frame_pose.h"
#include "core/tracking/projection_search.h"

namespace orbatlas {
namespace {

CameraCalibration pinhole() {
  CameraCalibration c;
  c.model = CameraModel::kPinholeRadTan;
  c.fx = 450.0;
  c.fy = 450.0;
  c.cx = 376.0;
  c.cy = 240.0;
  c.distortion = {0, 0, 0, 0};
  c.width = 752;
  c.height = 480;
  return c;
}

struct Scene {
  std::unique_ptr<Camera> camera = make_camera(pinhole());
  std::vector<Eigen::Vector3d> points;
  std::vector<Descriptor> descriptors;
  FrameCamera cam() const {
    FrameCamera fc;
    fc.camera = camera.get();
    return fc;
  }
};

Scene make_scene(std::size_t n, std::uint32_t seed = 7) {
  Scene s;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> x(-2.5, 2.5), y(-1.5, 1.5), z(3.0, 8.0);
  for (std::size_t i = 0; i < n; ++i) {
    s.points.emplace_back(x(rng), y(rng), z(rng));
    Descriptor d;
    for (auto& w : d) w = rng();
    s.descriptors.push_back(d);
  }
  return s;
}

// Features of the scene's visible points seen from T_w_c (level 0, angle 0, all
// under one vocabulary node); `index_of` maps keypoints back to points.
ImageFeatures observe(const Scene& s, const Pose3& T_w_c, std::vector<std::size_t>* index_of) {
  ImageFeatures f;
  f.width = 752;
  f.height = 480;
  const Pose3 T_c_w = T_w_c.inverse();
  for (std::size_t i = 0; i < s.points.size(); ++i) {
    Eigen::Vector2d uv;
    const Eigen::Vector3d p_c = T_c_w * s.points[i];
    if (p_c.z() <= 0.1 || !s.camera->project(p_c, &uv) || !s.camera->in_image(uv, 20.0)) continue;
    Keypoint kp;
    kp.uv = uv.cast<float>();
    f.keypoints.push_back(kp);
    f.descriptors.push_back(s.descriptors[i]);
    index_of->push_back(i);
  }
  compute_keypoint_geometry(*s.camera, f.keypoints);
  return f;
}

KeyFrameData keyframe_data(const Scene& s, const Pose3& T_w_c, std::vector<std::size_t>* index_of) {
  KeyFrameData d;
  d.T_w_b = T_w_c;  // body = camera
  d.features = observe(s, T_w_c, index_of);
  for (std::uint32_t i = 0; i < d.features.keypoints.size(); ++i) d.feature_vector[0].push_back(i);
  d.grid = FeatureGrid(d.features);
  return d;
}

Pose3 at(double x, double y, double z) { return Pose3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(x, y, z)); }

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

namespace orbatlas {
namespace {

// Tracking adds a keyframe's observations before local mapping processes it, so
// a newer keyframe waiting in the queue can be an older one's best covisible.
// Parents are chosen among older keyframes only, so the spanning tree stays a
// tree (a 2-cycle made culling fail on full MH_03).
TEST(LocalMapping, SpanningTreeParentIsAnOlderKeyframe) {
  const Scene s = make_scene(200, 11);
  Atlas atlas;
  auto map = atlas.create_map();
  std::vector<std::size_t> idx[3];
  std::shared_ptr<KeyFrame> kfs[3];
  for (int k = 0; k < 3; ++k) kfs[k] = map->new_keyframe(keyframe_data(s, at(0.1 * k, 0, 0), &idx[k]));
  auto slot_of = [](const std::vector<std::size_t>& v, std::size_t point) -> std::optional<std::size_t> {
    const auto it = std::find(v.begin(), v.end(), point);
    if (it == v.end()) return std::nullopt;
    return static_cast<std::size_t>(it - v.begin());
  };
  // The origin and the middle keyframe share 20 points; the middle and the newest 60.
  int shared01 = 0, shared12 = 0;
  for (std::size_t p = 0; p < s.points.size(); ++p) {
    const auto a = slot_of(idx[0], p), b = slot_of(idx[1], p), c = slot_of(idx[2], p);
    const bool with_origin = shared01 < 20 && a && b;
    const bool with_newest = !with_origin && shared12 < 60 && b && c;
    if (!with_origin && !with_newest) continue;
    MapPointData d;
    d.p_w = s.points[p];
    d.descriptor = s.descriptors[p];
    auto mp = map->new_map_point(d);
    kfs[1]->add_observation(*b, mp);
    kfs[with_origin ? 0 : 2]->add_observation(with_origin ? *a : *c, mp);
    mp->set_reference_keyframe(kfs[1]);
    (with_origin ? shared01 : shared12)++;
  }
  ASSERT_EQ(shared01, 20);
  ASSERT_EQ(shared12, 60);

  LocalMapperOptions o;
  o.run_bundle_adjustment = false;
  o.run_culling = false;
  LocalMapper mapper(atlas, s.cam(), o);
  for (const auto& kf : kfs) {
    mapper.insert(kf);
    mapper.wait_until_idle();
  }
  mapper.finish();
  EXPECT_EQ(kfs[0]->parent(), nullptr);  // the origin
  EXPECT_EQ(kfs[1]->parent(), kfs[0]);   // not the newer kfs[2], its best covisible
  ASSERT_NE(kfs[2]->parent(), nullptr);  // older: kfs[0] or kfs[1] (triangulation adds shared points)
  EXPECT_LT(kfs[2]->parent()->id(), kfs[2]->id());
}

// An error while processing one keyframe (here: in the processed-keyframe
// listener, where loop closing is fed) is contained: counted, the mapper goes
// on with the next keyframe, the session sees nothing. Only a long run of
// failures, a map that cannot be worked on, reaches the session.
TEST(LocalMapping, AnErrorInOneKeyframeIsCountedAndMappingGoesOn) {
  const Scene s = make_scene(200, 13);
  Atlas atlas;
  auto map = atlas.create_map();
  std::vector<std::shared_ptr<KeyFrame>> kfs;
  for (int k = 0; k < 6; ++k) {
    std::vector<std::size_t> idx;
    kfs.push_back(map->new_keyframe(keyframe_data(s, at(0.05 * k, 0, 0), &idx)));
  }
  LocalMapperOptions o;
  o.run_bundle_adjustment = false;
  o.run_culling = false;
  LocalMapper mapper(atlas, s.cam(), o);
  std::vector<KeyframeId> listened;
  mapper.set_processed_listener([&](const std::shared_ptr<KeyFrame>& kf) {
    listened.push_back(kf->id());
    if (kf->id() % 2 == 1) throw Error("injected failure in keyframe " + std::to_string(kf->id()));
  });
  for (const auto& kf : kfs) {
    EXPECT_NO_THROW(mapper.insert(kf));
    EXPECT_NO_THROW(mapper.wait_until_idle());
  }
  EXPECT_NO_THROW(mapper.finish());
  EXPECT_EQ(listened.size(), kfs.size());  // every keyframe was processed
  const LocalMapperStats stats = mapper.stats();
  EXPECT_EQ(stats.keyframes, kfs.size());
  EXPECT_EQ(stats.errors.errors, 3u);
  EXPECT_FALSE(stats.errors.fatal);
  EXPECT_NE(stats.errors.last.find("injected failure in keyframe 5"), std::string::npos) << stats.errors.last;
  // The map is intact: every keyframe still in it, each one's parent older.
  EXPECT_EQ(map->keyframe_count(), kfs.size());
  for (std::size_t k = 1; k < kfs.size(); ++k) {
    if (kfs[k]->parent()) {
      EXPECT_LT(kfs[k]->parent()->id(), kfs[k]->id());
    }
  }
}

// The first keyframe a mapper processes stays in processing (in its processed
// listener, after its local BA and culling) until `release` is set; `entered`
// is set once it is there. Declared before the mapper, which calls it.
struct FirstKeyframeHold {
  std::promise<void> entered, release;
  std::shared_future<void> released = release.get_future().share();
  bool first = true;
  void attach(LocalMapper& mapper) {
    mapper.set_processed_listener([this](const std::shared_ptr<KeyFrame>&) {
      if (!std::exchange(first, false)) return;
      entered.set_value();
      released.wait();
    });
  }
};

// Tracking's wait for its last keyframe (Tracker::wait_for_mapping): a
// keyframe counts as adjusted once its local BA and culling are done, before
// the rest of its processing (here the listener holds it); one queued behind
// another session's keyframe is not adjusted until it has been processed.
TEST(LocalMapping, AKeyframeIsAdjustedBeforeItsProcessingEndsAndWaitsAreBounded) {
  const Scene s = make_scene(200, 29);
  Atlas atlas;
  auto map = atlas.create_map();
  LocalMapperOptions o;
  o.run_culling = false;
  FirstKeyframeHold hold;
  LocalMapper mapper(atlas, s.cam(), o);
  hold.attach(mapper);
  using std::chrono::milliseconds;
  EXPECT_TRUE(mapper.wait_until_adjusted(1, milliseconds(0)));  // nothing handed in
  std::vector<std::size_t> idx;
  ASSERT_TRUE(mapper.insert(map->new_keyframe(keyframe_data(s, at(0.0, 0, 0), &idx)), 1));
  ASSERT_TRUE(mapper.insert(map->new_keyframe(keyframe_data(s, at(0.05, 0, 0), &idx)), 2));
  hold.entered.get_future().wait();
  EXPECT_TRUE(mapper.wait_until_adjusted(1, milliseconds(0)));  // adjusted, still in processing
  EXPECT_FALSE(mapper.idle(1));
  const auto start = std::chrono::steady_clock::now();
  EXPECT_FALSE(mapper.wait_until_adjusted(2, milliseconds(50)));  // queued behind it: the wait is cut
  EXPECT_GE(std::chrono::steady_clock::now() - start, milliseconds(50));
  hold.release.set_value();
  EXPECT_TRUE(mapper.wait_until_adjusted(2, milliseconds(10000)));
  mapper.finish();
  EXPECT_EQ(mapper.stats().keyframes, 2u);
}

// Sessions sharing a mapper (sources): a keyframe of one in processing makes
// the mapper busy for that session only, so another session still makes its
// keyframes as it would alone (ORB-SLAM's AcceptKeyFrames, per session).
TEST(LocalMapping, IdleIsPerSourceWhenSessionsShareAMapper) {
  const Scene s = make_scene(200, 23);
  Atlas atlas;
  auto map = atlas.create_map();
  LocalMapperOptions o;
  o.run_bundle_adjustment = false;
  o.run_culling = false;
  FirstKeyframeHold hold;
  LocalMapper mapper(atlas, s.cam(), o);
  hold.attach(mapper);
  std::vector<std::size_t> idx;
  EXPECT_TRUE(mapper.idle(1));
  EXPECT_TRUE(mapper.insert(map->new_keyframe(keyframe_data(s, at(0.0, 0, 0), &idx)), 1));
  hold.entered.get_future().wait();
  EXPECT_FALSE(mapper.idle());   // the mapper is working
  EXPECT_FALSE(mapper.idle(1));  // on source 1's keyframe
  EXPECT_TRUE(mapper.idle(2));   // source 2 has nothing pending
  EXPECT_TRUE(mapper.insert(map->new_keyframe(keyframe_data(s, at(0.05, 0, 0), &idx)), 2));
  EXPECT_FALSE(mapper.idle(2));  // queued behind source 1's
  EXPECT_EQ(mapper.queued(), 1u);
  hold.release.set_value();
  mapper.wait_until_idle();
  EXPECT_TRUE(mapper.idle(1));
  EXPECT_TRUE(mapper.idle(2));
  EXPECT_TRUE(mapper.idle());
  mapper.finish();
  EXPECT_EQ(mapper.stats().keyframes, 2u);
}

TEST(LocalMapping, FailingOnEveryKeyframeFailsTheSessionAtLast) {
  const Scene s = make_scene(100, 17);
  Atlas atlas;
  auto map = atlas.create_map();
  LocalMapperOptions o;
  o.run_bundle_adjustment = false;
  o.run_culling = false;
  LocalMapper mapper(atlas, s.cam(), o);
  mapper.set_processed_listener([](const std::shared_ptr<KeyFrame>&) { throw Error("the map is broken"); });
  bool failed = false;
  for (int k = 0; k < 40 && !failed; ++k) {
    std::vector<std::size_t> idx;
    try {
      mapper.insert(map->new_keyframe(keyframe_data(s, at(0.01 * k, 0, 0), &idx)));
      mapper.wait_until_idle();
    } catch (const WorkerFailed& e) {
      failed = true;
      EXPECT_NE(std::string(e.what()).find("local mapping failed 20 times in a row"), std::string::npos) << e.what();
      EXPECT_EQ(k, 19);  // raised by the wait after the 20th keyframe
    }
  }
  EXPECT_TRUE(failed);
  EXPECT_TRUE(mapper.stats().errors.fatal);
  EXPECT_THROW(mapper.finish(), WorkerFailed);
}

// Local mapping belongs to the map: sessions (sinks) tracking in one map feed
// its one mapper; a map paused for a loop correction takes no keyframes, also
// before it has a mapper; a merge hands the merged map's mapping over; a map
// nobody maps lets its mapper go and gets a new one with its next keyframe.
TEST(MappingWorkers, SessionsInOneMapFeedOneMapper) {
  const Scene s = make_scene(200, 19);
  Atlas atlas;
  auto a = atlas.create_map();
  auto b = atlas.create_map();
  MappingWorkersOptions o;
  o.mapper.run_bundle_adjustment = false;
  o.mapper.run_culling = false;
  o.loop_closing = false;
  MappingWorkers workers(atlas, s.cam(), o);
  const auto first = workers.attach();
  const auto second = workers.attach();
  const auto keyframe = [&s](Map& map, double x) {
    std::vector<std::size_t> idx;
    return map.new_keyframe(keyframe_data(s, at(x, 0, 0), &idx));
  };
  EXPECT_TRUE(first->accepting(a->id()));
  EXPECT_TRUE(first->idle(a->id()));  // no mapper yet: nothing queued
  for (int k = 0; k < 3; ++k) {
    first->insert(keyframe(*a, 0.05 * k));
    second->insert(keyframe(*a, 0.05 * k + 0.02));
  }
  EXPECT_EQ(workers.mapped_maps(), (std::vector<MapId>{a->id()}));  // one mapper for both sessions
  second->insert(keyframe(*b, 0.5));
  EXPECT_EQ(workers.mapped_maps(), (std::vector<MapId>{a->id(), b->id()}));
  workers.wait_until_idle();
  EXPECT_EQ(workers.mapping_stats().keyframes, 7u);

  workers.pause(a->id());
  EXPECT_FALSE(first->accepting(a->id()));
  EXPECT_TRUE(second->accepting(b->id()));
  workers.resume(a->id());
  EXPECT_TRUE(first->accepting(a->id()));
  const MapId later = a->id() + 100;  // a map without a mapper stays paused too
  workers.pause(later);
  EXPECT_FALSE(first->accepting(later));
  workers.resume(later);
  EXPECT_TRUE(first->accepting(later));

  // b merged into a (both paused, as the loop closer does): b's mapping ends.
  workers.pause(a->id());
  workers.pause(b->id());
  workers.merged(b->id(), a->id());
  workers.resume(b->id());
  workers.resume(a->id());
  EXPECT_EQ(workers.mapped_maps(), (std::vector<MapId>{a->id()}));
  // Nobody maps a now: its mapper goes; a keyframe later starts a new one.
  workers.retire(a->id());
  EXPECT_TRUE(workers.mapped_maps().empty());
  first->insert(keyframe(*a, 0.3));
  EXPECT_EQ(workers.mapped_maps(), (std::vector<MapId>{a->id()}));
  workers.finish();
  const LocalMapperStats stats = workers.mapping_stats();
  EXPECT_EQ(stats.keyframes, 8u);  // every mapper's figures, the retired ones' too
  EXPECT_EQ(stats.errors.errors, 0u);
  EXPECT_THROW(first->insert(keyframe(*a, 0.4)), Error);
  EXPECT_THROW(workers.attach(), Error);
}

}  // namespace
}  // namespace orbatlas
