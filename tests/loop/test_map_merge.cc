// Map merging on two simulated sessions whose paths through the Machine Hall
// overlap (MH_01 from 46 s and MH_02 from 38 s both fly from the take-off spot
// towards the middle of the hall): each session builds its own map in its own
// frame; place recognition over the second map's keyframes, looking in the
// other maps, finds the shared place; the merge moves the second map into the
// first one's world. Checked against the ground truth, which puts both
// recordings in one world frame: after the merge both trajectories fit it with
// ONE rigid alignment (before it, they do not).
#include <gtest/gtest.h>

#include <algorithm>

#include <opencv2/imgcodecs.hpp>

#include "core/common/data_paths.h"
#include "core/eval/evaluate.h"
#include "core/io/tum_trajectory.h"
#include "core/optimization/apply_global_adjustment.h"
#include "core/loop/map_merge.h"
#include "core/loop/place_recognizer.h"
#include "core/slam/slam_system.h"
#include "core/tracking/stereo_frontend.h"
#include "core/vocabulary/default_vocabulary.h"
#include "tests/support/slam_test_clip.h"

namespace orbatlas {
namespace {

struct Session {
  std::vector<FrameAnchor> anchors;
  Trajectory ground_truth;
  MapId map = 0;                     // the map its last frame was tracked in
  std::vector<TrackResult> results;  // per frame
  SlamStats stats;
};

// Each session keeps to its own map (relocalisation may not enter another);
// with `live_merging` its map may be merged into another while it runs. With
// monocular settings the left images only are sent, and the ground truth is
// the camera's (a single camera's body is its camera).
Session run_session(Atlas& atlas, const std::filesystem::path& clip, const SlamSettings& settings,
                    const Vocabulary& vocabulary, bool live_merging = false) {
  const EurocDataset dataset = test::stereo_dataset(clip);
  const bool monocular = settings.sensor == SensorType::kMonocular;
  Session s;
  s.ground_truth = from_ground_truth_states(dataset.ground_truth);
  if (monocular) {
    const Pose3 T_b_c = StereoFrontend(settings, false).calibration().T_b_c;  // the rectified left camera
    for (auto& p : s.ground_truth) p.pose = p.pose * T_b_c;
  }
  SlamSystemOptions o;
  o.synchronous_mapping = true;  // deterministic
  o.live_merging = live_merging;
  SessionWiring wiring;
  wiring.may_enter_map = [](MapId) { return false; };
  SlamSystem slam(atlas, settings, vocabulary, o, wiring);
  for (const auto& f : pair_stereo_frames(dataset))
    s.results.push_back(slam.process(f.t_ns, cv::imread(f.left.string(), cv::IMREAD_GRAYSCALE),
                                     monocular ? cv::Mat() : cv::imread(f.right.string(), cv::IMREAD_GRAYSCALE)));
  slam.finish();
  s.anchors = slam.anchors();
  s.stats = slam.stats();
  EXPECT_FALSE(s.anchors.empty());
  if (!s.anchors.empty()) s.map = s.anchors.back().map;
  return s;
}

// Both sessions' frames, as the atlas places them now, against both ground truths.
double joint_ate(const Atlas& atlas, const std::vector<const Session*>& sessions) {
  std::vector<Trajectory> estimates, ground_truths;
  for (const Session* s : sessions) {
    Trajectory estimate;
    for (const auto& a : s->anchors)
      if (const auto pose = atlas.frame_pose(a)) estimate.push_back({a.t_ns, *pose});
    estimates.push_back(std::move(estimate));
    ground_truths.push_back(s->ground_truth);
  }
  return evaluate_trajectory(join_trajectories(estimates, "estimates"),
                             join_trajectories(ground_truths, "ground truth"))
      .ate.rmse;
}

// MH_01 from 46 s and MH_02 from 38 s, 8 s each (removed at the end), with the
// shipped stereo settings and vocabulary.
struct OverlappingClips {
  std::filesystem::path a = test::simulated_clip("MH_01", 46.0, 8.0);
  test::ClipCleanup cleanup_a{a};
  std::filesystem::path b = test::simulated_clip("MH_02", 38.0, 8.0);
  test::ClipCleanup cleanup_b{b};
  SlamSettings settings = read_settings(shipped_config_dir() / "euroc" / "stereo.yaml", SensorType::kStereo);
  Vocabulary vocabulary = Vocabulary::load(default_vocabulary_path());
};

TEST(MapMerge, TwoOverlappingSessionsBecomeOneMapInOneFrame) {
  const OverlappingClips clips;
  const SlamSettings& settings = clips.settings;
  const Vocabulary& vocabulary = clips.vocabulary;
  const auto &clip_a = clips.a, &clip_b = clips.b;

  Atlas atlas;
  const Session a = run_session(atlas, clip_a, settings, vocabulary);
  const Session b = run_session(atlas, clip_b, settings, vocabulary);
  ASSERT_EQ(atlas.maps().size(), 2u);
  ASSERT_NE(a.map, b.map);
  const std::size_t keyframes = atlas.map(a.map)->keyframe_count() + atlas.map(b.map)->keyframe_count();
  const double ate_apart = joint_ate(atlas, {&a, &b});

  // The camera the maps were made with.
  StereoFrontend frontend(settings, false);
  const FrameCamera cam = frontend.frame_camera();

  // A recogniser that may not use map A finds nothing.
  PlaceRecognitionOptions ro;
  ro.scope = PlaceScope::kOtherMaps;
  {
    PlaceRecognitionOptions none = ro;
    none.may_use_map = [](MapId) { return false; };
    PlaceRecognizer refused(atlas.keyframe_index(), cam, none);
    for (const auto& kf : atlas.map(b.map)->keyframes()) EXPECT_FALSE(refused.process(kf).match.has_value());
  }

  PlaceRecognizer recognizer(atlas.keyframe_index(), cam, ro);
  std::optional<PlaceMatch> match;
  for (const auto& kf : atlas.map(b.map)->keyframes()) {
    if (auto step = recognizer.process(kf); step.match) {
      match = std::move(step.match);
      break;
    }
  }
  ASSERT_TRUE(match.has_value()) << "the shared starting place was not recognised";
  EXPECT_EQ(match->current->map_id(), b.map);
  EXPECT_EQ(match->matched->map_id(), a.map);
  EXPECT_GE(match->verified_keyframes, 3);

  const MapMergeStats merged = merge_maps(atlas, *match, cam);
  ASSERT_EQ(atlas.maps().size(), 1u);
  EXPECT_EQ(atlas.maps().front()->id(), a.map);
  EXPECT_EQ(atlas.maps().front()->keyframe_count(), keyframes);
  EXPECT_GT(merged.new_links, 0u);
  // One spanning tree: every keyframe reaches the map's root.
  std::size_t roots = 0;
  for (const auto& kf : atlas.maps().front()->keyframes()) roots += kf->parent() ? 0 : 1;
  EXPECT_EQ(roots, 1u);

  const double ate_merged = joint_ate(atlas, {&a, &b});
  Map& map = *atlas.maps().front();
  const GlobalBundleAdjustmentResult ba = global_bundle_adjustment(map, *cam.camera, cam.bf);
  apply_global_adjustment(map, ba, cam.pyramid);
  const double ate_refined = joint_ate(atlas, {&a, &b});
  EXPECT_GT(ate_apart, 0.1);      // two maps, two frames: one alignment cannot fit both
  EXPECT_LT(ate_merged, 0.009);   // measured 0.0046 m
  EXPECT_LT(ate_refined, 0.008);  // measured 0.0038 m
}

// Live merging: the second session starts a map of its own (it may not
// relocalise into the first one), and while it is still running, place
// recognition over the other maps finds the first session's map; its map is
// merged into that one and tracking follows: the frames after the merge are
// tracked in the first map, in its frame.
TEST(MapMerge, ARunningSessionsMapIsMergedLiveAndTrackingFollows) {
  const OverlappingClips clips;
  const SlamSettings& settings = clips.settings;
  const Vocabulary& vocabulary = clips.vocabulary;
  const auto &clip_a = clips.a, &clip_b = clips.b;

  Atlas atlas;
  const Session a = run_session(atlas, clip_a, settings, vocabulary, true);
  EXPECT_TRUE(a.stats.loop.merges.empty());  // alone in the atlas: nothing to merge with
  const Session b = run_session(atlas, clip_b, settings, vocabulary, true);

  ASSERT_EQ(b.stats.loop.merges.size(), 1u) << "the second session's map was not merged while it ran";
  const LiveMerge& merge = b.stats.loop.merges.front();
  EXPECT_EQ(merge.merge.target, a.map);
  EXPECT_NE(merge.merge.source, a.map);
  EXPECT_GE(merge.verified_keyframes, 3);
  ASSERT_FALSE(b.results.empty());
  EXPECT_EQ(b.results.front().map, merge.merge.source);  // it started on its own
  // Every frame after the merge is tracked, in the first session's map.
  std::size_t after = 0;
  for (const auto& r : b.results) {
    if (r.t_ns <= merge.current_t_ns + 200'000'000) continue;  // the keyframe's mapping and closing take a few frames
    ++after;
    EXPECT_TRUE(r.tracked) << "frame at " << r.t_ns << " ns";
    EXPECT_EQ(r.map, a.map) << "frame at " << r.t_ns << " ns";
  }
  EXPECT_GT(after, 20u) << "merged too late to show tracking following";
  EXPECT_EQ(b.map, a.map);

  ASSERT_EQ(atlas.maps().size(), 1u);
  std::size_t roots = 0;
  for (const auto& kf : atlas.maps().front()->keyframes()) roots += kf->parent() ? 0 : 1;
  EXPECT_EQ(roots, 1u);
  const double ate = joint_ate(atlas, {&a, &b});
  EXPECT_LT(ate, 0.007);  // measured 0.0033 m
}

// A single camera of the same rig (its left camera, rectified as the stereo
// maps' keyframes are) maps at its own scale, recognises the stored stereo
// map, and the merge, a similarity, gives its map the stereo map's metric
// scale: afterwards both sessions fit the ground truth under ONE rigid
// alignment, its earlier frames included.
TEST(MapMerge, AMonocularSessionMergedIntoAStereoMapBecomesMetric) {
  const OverlappingClips clips;
  SlamSettings mono = clips.settings;
  mono.sensor = SensorType::kMonocular;  // the rig's left camera alone

  Atlas atlas;
  const Session a = run_session(atlas, clips.a, clips.settings, clips.vocabulary, true);
  const Session b = run_session(atlas, clips.b, mono, clips.vocabulary, true);

  ASSERT_EQ(b.stats.loop.merges.size(), 1u) << "the monocular map was not merged into the stereo one";
  const LiveMerge& merge = b.stats.loop.merges.front();
  EXPECT_EQ(merge.merge.target, a.map);
  EXPECT_EQ(b.map, a.map);
  EXPECT_NE(merge.merge.scale, 1.0);  // its map had a scale of its own
  ASSERT_EQ(atlas.maps().size(), 1u);

  const double ate = joint_ate(atlas, {&a, &b});
  Trajectory b_frames;
  for (const auto& anchor : b.anchors)
    if (const auto pose = atlas.frame_pose(anchor)) b_frames.push_back({anchor.t_ns, *pose});
  EvalOptions sim3;
  sim3.align = AlignMode::kSim3;
  const EvalResult b_alone = evaluate_trajectory(b_frames, b.ground_truth, sim3);
  EXPECT_LT(std::abs(b_alone.alignment.scale - 1.0), 0.012);  // measured -0.0058
  EXPECT_LT(ate, 0.011);                                      // measured 0.0052 m
  std::size_t after = 0;
  for (const auto& r : b.results) {
    if (r.t_ns <= merge.current_t_ns + 200'000'000) continue;
    ++after;
    EXPECT_TRUE(r.tracked && r.map == a.map) << "frame at " << r.t_ns << " ns";
  }
  EXPECT_GT(after, 100u);  // merged within ~1 s of its map's start (measured 1.10 s)
}

// The reverse order: a metric (stereo) session neither enters nor merges into
// a map of free scale (a monocular one), whose lengths would disagree with its
// own; both maps stay, each in its own units.
TEST(MapMerge, AStereoSessionLeavesAMonocularMapAlone) {
  const OverlappingClips clips;
  SlamSettings mono = clips.settings;
  mono.sensor = SensorType::kMonocular;

  Atlas atlas;
  const Session b = run_session(atlas, clips.b, mono, clips.vocabulary, true);
  const Session a = run_session(atlas, clips.a, clips.settings, clips.vocabulary, true);
  EXPECT_TRUE(a.stats.loop.merges.empty());
  EXPECT_NE(a.map, b.map);
  ASSERT_EQ(atlas.maps().size(), 2u);
  EXPECT_FALSE(atlas.map(b.map)->metric_scale());
  EXPECT_TRUE(atlas.map(a.map)->metric_scale());
}

// A merge moves the source map into the target's units: a map of free scale
// (monocular) may go into any map, a metric one (measured depths, or an IMU)
// only into a metric one (the loop closer refuses the rest; the free map may
// join it from its own side later).
TEST(MapMerge, AMetricMapIsNeverMergedIntoOneOfFreeScale) {
  Atlas atlas;
  KeyFrameData mono;
  mono.features.keypoints.resize(2);
  mono.depth.assign(2, -1.0f);
  mono.u_right.assign(2, -1.0f);
  KeyFrameData stereo = mono;
  stereo.depth[0] = 3.0f;
  stereo.u_right[0] = 200.0f;
  auto mono_map = atlas.create_map();
  mono_map->new_keyframe(mono);
  auto stereo_map = atlas.create_map();
  stereo_map->new_keyframe(stereo);
  auto inertial_map = atlas.create_map();
  inertial_map->new_keyframe(mono);
  inertial_map->set_inertial_state(Map::InertialState{});
  EXPECT_TRUE(merge_keeps_scale(*mono_map, *stereo_map));
  EXPECT_TRUE(merge_keeps_scale(*mono_map, *inertial_map));
  EXPECT_TRUE(merge_keeps_scale(*stereo_map, *inertial_map));
  EXPECT_TRUE(merge_keeps_scale(*inertial_map, *stereo_map));
  EXPECT_FALSE(merge_keeps_scale(*stereo_map, *mono_map));
  EXPECT_FALSE(merge_keeps_scale(*inertial_map, *mono_map));
}

// A monocular-inertial map whose IMU scale has not settled (before its second
// refinement) is merged in Sim(3): scaled to the target's units (positions,
// keyframe units, IMU velocities), then turned about gravity and moved so the
// current keyframe lands where the match puts it. Exact on a synthetic pair.
TEST(MapMerge, AnInertialMonocularMapWhoseScaleHasNotSettledTakesTheTargetsScale) {
  Atlas atlas;
  KeyFrameData mono;
  mono.features.keypoints.resize(2);
  mono.depth.assign(2, -1.0f);
  mono.u_right.assign(2, -1.0f);
  auto source = atlas.create_map();
  KeyFrameData first = mono, second = mono;
  second.timestamp_ns = 500'000'000;
  second.T_w_b = Pose3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(1.0, 0.0, 0.0));
  auto k0 = source->new_keyframe(first);
  auto k1 = source->new_keyframe(second);
  k1->set_imu_state(KeyFrame::ImuState{Eigen::Vector3d(0.5, 0.0, 0.0), ImuBias{}});
  source->set_inertial_state(Map::InertialState{});  // initialised, not refined
  auto target = atlas.create_map();
  KeyFrameData stereo = mono;
  stereo.depth[0] = 3.0f;
  stereo.u_right[0] = 200.0f;
  auto m = target->new_keyframe(stereo);
  target->set_inertial_state(Map::InertialState{});

  // The source's world in the target's: a turn of 30 deg about z, a move, and
  // 1.25 target metres per source unit (what the match estimated).
  const Sim3 S_wt_ws(Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 6.0, Eigen::Vector3d::UnitZ())),
                     Eigen::Vector3d(5.0, 2.0, 0.0), 1.25);
  PlaceMatch match;
  match.current = k1;
  match.matched = m;
  match.detected_on = m;
  match.scale_free = true;
  match.S_c_w_corrected = Sim3(k1->T_w_c().inverse()) * S_wt_ws.inverse();
  const MapMergeStats stats = merge_maps(atlas, match, FrameCamera{});
  EXPECT_NEAR(stats.scale, 1.25, 1e-12);
  EXPECT_TRUE(stats.four_dof);
  ASSERT_EQ(atlas.maps().size(), 1u);
  const Eigen::Vector3d expected_k1 = S_wt_ws * Eigen::Vector3d(1.0, 0.0, 0.0);
  EXPECT_LT((k1->T_w_b().t - expected_k1).norm(), 1e-12);
  EXPECT_LT((k0->T_w_b().t - S_wt_ws.t).norm(), 1e-12);
  EXPECT_NEAR(k1->units(), 1.25, 1e-12);
  EXPECT_LT((k1->imu_state()->v_i - Eigen::Vector3d(0.625, 0.0, 0.0)).norm(), 1e-12);  // in its IMU frame
}

}  // namespace
}  // namespace orbatlas
