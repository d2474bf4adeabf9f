// Loop closing end to end on a simulated revisit: MH_02 from 117 s, where the
// drone leaves its starting point by up to 6.7 m and comes back after ~20 s.
// Tracking on the rendered hall drifts by millimetres only, so re-entering the
// start is tracked straight into the old keyframes (the small hall keeps them
// covisible through far walls: no loop is needed). The test therefore makes
// what a long excursion leaves behind — half-way, the part of the map after the
// first 3 s is moved (drift) and stops sharing points with the start — and
// checks that the revisit is recognised as a loop, that the correction is about
// the injected drift and that the trajectory ends within 3 cm. Loop closing runs
// on a shared worker thread, as in the server (test_slam runs it on its own).
// A monocular map drifts in scale too: there the injected drift is a
// similarity, and the loop must undo its scale (Sim(3) loop closing).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <unordered_set>
#include <opencv2/imgcodecs.hpp>

#include "core/common/data_paths.h"
#include "core/eval/evaluate.h"
#include "core/slam/slam_system.h"
#include "core/vocabulary/default_vocabulary.h"
#include "core/io/imu_batches.h"
#include "tests/support/slam_test_clip.h"

namespace orbatlas {
namespace {

// What a long excursion leaves behind, made on purpose: the keyframes made
// after `after_ns` (and the points they are the reference of) are moved by
// `delta` (drift), and no point is shared any more between them and the older
// keyframes (each shared point keeps only the observers on its reference
// keyframe's side), so the two parts are linked by the spanning tree only and
// tracking cannot reach the old part through the covisibility graph.
void inject_drift(Map& map, TimestampNs after_ns, const Sim3& delta) {
  std::unordered_set<KeyframeId> moved;
  for (const auto& kf : map.keyframes()) {
    if (kf->timestamp_ns() <= after_ns) continue;
    const Pose3 T = kf->T_w_b();
    kf->set_T_w_b(Pose3(delta.q * T.q, delta * T.t));
    kf->scale_units(delta.s);  // the frames tracked there drifted with it
    moved.insert(kf->id());
  }
  for (const auto& mp : map.map_points()) {
    const auto ref = mp->reference_keyframe_id();
    if (!ref) continue;
    const bool new_side = moved.count(*ref) > 0;
    if (new_side) {
      mp->set_p_w(delta * mp->p_w());
      mp->set_normal(delta.q * mp->normal());
      mp->set_distances(static_cast<float>(delta.s * mp->min_distance()),
                        static_cast<float>(delta.s * mp->max_distance()));
    }
    for (const auto& obs : mp->observations()) {
      const auto kf = obs.kf.lock();
      if (kf && (moved.count(kf->id()) > 0) != new_side) kf->erase_slot(obs.slot);
    }
    if (mp->observation_count() == 0) map.cull_map_point(mp->id());
  }
  for (const auto& kf : map.keyframes()) kf->update_connections();
}

Trajectory as_trajectory(const std::vector<TimedPose>& poses) {
  Trajectory t;
  for (const auto& p : poses) t.push_back({p.t_ns, p.T_w_b});
  return t;
}

struct DriftCase {
  std::string config;        // the shipped stereo, stereo-inertial or monocular settings
  double drift_scale = 1.0;  // a monocular map's scale drift (1: metric maps)
  double max_ate = 0.0;      // SE3 (Sim3 for a monocular map)
  double max_keyframe_ate = 0.0;
  std::size_t max_untracked = 0;  // a monocular map starts a few frames in
};

// The IMU is fed before each frame, as a device sends it.
void injected_drift_case(const DriftCase& c) {
  const auto clip = test::simulated_clip("MH_02", 117.0, 23.0);
  test::ClipCleanup cleanup{clip};
  const EurocDataset dataset = test::stereo_dataset(clip);
  const auto frames = pair_stereo_frames(dataset);
  Trajectory gt;
  for (const auto& s : dataset.ground_truth) gt.push_back({s.t_ns, s.T_w_b});

  const SlamSettings settings = read_settings(shipped_config_dir() / "euroc" / c.config);
  const Vocabulary vocabulary = Vocabulary::load(default_vocabulary_path());
  Atlas atlas;
  SlamSystemOptions o;
  o.synchronous_mapping = true;  // deterministic, and the map is quiet between frames
  // Loop closing on a thread shared with other sessions, as in the server.
  SessionWiring wiring;
  wiring.loop_worker = std::make_shared<SerialWorker>(8);
  SlamSystem slam(atlas, settings, vocabulary, o, wiring);
  const bool monocular = settings.sensor == SensorType::kMonocular;
  EvalOptions eval_options;
  if (monocular) {
    eval_options.align = AlignMode::kSim3;
    eval_options.estimate_T_b_x = dataset.cameras[0].calibration.T_b_c;  // a single camera's body is the camera
  }

  const TimestampNs t0 = frames.front().t_ns;
  const std::size_t inject_at = 200;  // 10 s in: several metres away from the start
  const double drift_m = 0.5, drift_deg = 6.0;
  std::size_t imu_next = 0;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const auto& f = frames[i];
    if (slam.inertial()) slam.add_imu(take_imu_batch(dataset.imu, imu_next, f.t_ns));
    slam.process(f.t_ns, cv::imread(f.left.string(), cv::IMREAD_GRAYSCALE),
                 monocular ? cv::Mat() : cv::imread(f.right.string(), cv::IMREAD_GRAYSCALE));
    if (i == inject_at) {
      // A yaw (and a scale) about the current position plus a shift: what
      // odometry drift looks like.
      const auto map = atlas.active_map();
      const Eigen::Vector3d pivot = slam.trajectory().back().T_w_b.t;
      const Eigen::Quaterniond yaw(Eigen::AngleAxisd(drift_deg * M_PI / 180.0, Eigen::Vector3d::UnitZ()));
      // A monocular map's units per metre: the inverse of its Sim3 alignment's scale so far.
      const double units_per_m =
          monocular ? 1.0 / evaluate_trajectory(as_trajectory(slam.trajectory()), gt, eval_options).alignment.scale
                    : 1.0;
      const double shift = drift_m * units_per_m;
      const Sim3 delta = Sim3(Eigen::Quaterniond::Identity(), pivot + Eigen::Vector3d(shift, 0.0, 0.0)) *
                         Sim3(yaw, Eigen::Vector3d::Zero(), c.drift_scale) *
                         Sim3(Eigen::Quaterniond::Identity(), -pivot);
      inject_drift(*map, t0 + 3'000'000'000, delta);
    }
  }
  slam.finish();
  const SlamStats stats = slam.stats();
  ASSERT_TRUE(stats.loop_closing);
  ASSERT_GE(stats.loop.loops.size(), 1u) << "the revisit was not recognised";
  const ClosedLoop& loop = stats.loop.loops.front();
  // The loop ties the revisit to the start, and undoes about the injected drift.
  EXPECT_LT(loop.matched_t_ns, t0 + 3'000'000'000);
  if (!monocular) {
    EXPECT_GT(loop.correction.correction_m, 0.5 * drift_m);
    EXPECT_LT(loop.correction.correction_m, 3.0 * drift_m);
    EXPECT_EQ(loop.correction.correction_scale, 1.0);
  } else {
    // The scale drift is undone: lengths near the revisit shrink back by about 1 / drift.
    EXPECT_NEAR(loop.correction.correction_scale, 1.0 / c.drift_scale, 0.25 * (c.drift_scale - 1.0));
  }
  EXPECT_EQ(stats.maps, 1u);
  EXPECT_LE(stats.frames - stats.tracked, c.max_untracked);

  // An inertial map is corrected in yaw and translation only, and its global
  // BA keeps the IMU terms of its chain.
  EXPECT_EQ(loop.correction.four_dof, slam.inertial());
  ASSERT_GE(stats.loop.global_adjustments.size(), 1u);
  const GlobalAdjustmentRun& global = stats.loop.global_adjustments.front();
  if (!global.interrupted) {
    EXPECT_EQ(global.inertial_edges > 0, slam.inertial());
  }

  const EvalResult eval = evaluate_trajectory(as_trajectory(slam.trajectory()), gt, eval_options);
  EXPECT_LT(eval.ate.rmse, c.max_ate) << "ATE over " << eval.ate.count << " poses";
  // The keyframes themselves, which the loop and the global BA moved.
  Trajectory keyframes;
  for (const auto& kf : atlas.active_map()->keyframes()) keyframes.push_back({kf->timestamp_ns(), kf->T_w_b()});
  std::sort(keyframes.begin(), keyframes.end(), [](const auto& a, const auto& b) { return a.t_ns < b.t_ns; });
  const EvalResult eval_keyframes = evaluate_trajectory(keyframes, gt, eval_options);
  EXPECT_LT(eval_keyframes.ate.rmse, c.max_keyframe_ate) << "ATE over " << eval_keyframes.ate.count << " keyframes";
}

TEST(LoopClosing, InjectedDriftIsDetectedAndCorrectedOnRevisit) {
  injected_drift_case({.config = "stereo.yaml", .max_ate = 0.012, .max_keyframe_ate = 0.01});
  // measured 0.0058 m; keyframes 0.0046 m
}

TEST(LoopClosing, AnInertialMapIsCorrectedInYawAndTranslation) {
  injected_drift_case({.config = "stereo_inertial.yaml", .max_ate = 0.008, .max_keyframe_ate = 0.006});
  // measured 0.0040 m; keyframes 0.0027 m
}

// A monocular map's scale drifts with its odometry: the injected drift scales
// the excursion by 1.25 as well, and the loop, a similarity, undoes it
// (measured: scale 0.786 at the revisit). The keyframes end as close to the
// ground truth as the metric maps'; the frames follow their keyframes' units
// (FrameAnchor), and end 0.0103 m off (0.0087 m in the first 3 s, which the
// drift and the loop never touched: frames are tracked poses, keyframes
// bundle-adjusted ones).
TEST(LoopClosing, AMonocularMapsScaleDriftIsUndoneBySim3) {
  injected_drift_case({.config = "mono.yaml",
                       .drift_scale = 1.25,
                       .max_ate = 0.02,            // measured 0.0103 m
                       .max_keyframe_ate = 0.006,  // measured 0.0029 m
                       .max_untracked = 20});
}

}  // namespace
}  // namespace orbatlas
