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
#include <gtest/gtest.h>

#include <cmath>
#include <unordered_set>
#include <opencv2/imgcodecs.hpp>

#include "core/common/data_paths.h"
#include "core/eval/evaluate.h"
#include "core/slam/stereo_slam.h"
#include "core/vocabulary/default_vocabulary.h"
#include "core/io/imu_batches.h"
#include "tests/slam_test_clip.h"

namespace orbatlas {
namespace {

// What a long excursion leaves behind, made on purpose: the keyframes made
// after `after_ns` (and the points they are the reference of) are moved by
// `delta` (drift), and no point is shared any more between them and the older
// keyframes (each shared point keeps only the observers on its reference
// keyframe's side), so the two parts are linked by the spanning tree only and
// tracking cannot reach the old part through the covisibility graph.
void inject_drift(Map& map, TimestampNs after_ns, const Pose3& delta) {
  std::unordered_set<KeyframeId> moved;
  for (const auto& kf : map.keyframes()) {
    if (kf->timestamp_ns() <= after_ns) continue;
    kf->set_T_w_b(delta * kf->T_w_b());
    moved.insert(kf->id());
  }
  for (const auto& mp : map.map_points()) {
    const auto ref = mp->reference_keyframe_id();
    if (!ref) continue;
    const bool new_side = moved.count(*ref) > 0;
    if (new_side) mp->set_p_w(delta * mp->p_w());
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

// `config`: the shipped stereo or stereo-inertial settings (the IMU is fed
// before each frame, as a device sends it).
void injected_drift_case(const std::string& config, double max_ate) {
  const auto clip = test::simulated_clip("MH_02", 117.0, 23.0);
  test::ClipCleanup cleanup{clip};
  const EurocDataset dataset = test::stereo_dataset(clip);
  const auto frames = pair_stereo_frames(dataset);
  Trajectory gt;
  for (const auto& s : dataset.ground_truth) gt.push_back({s.t_ns, s.T_w_b});

  const SlamSettings settings = read_settings(shipped_config_dir() / "euroc" / config, SensorType::kStereo);
  const Vocabulary vocabulary = Vocabulary::load(default_vocabulary_path());
  Atlas atlas;
  StereoSlamOptions o;
  o.synchronous_mapping = true;  // deterministic, and the map is quiet between frames
  // Loop closing on a thread shared with other sessions, as in the server.
  SessionWiring wiring;
  wiring.loop_worker = std::make_shared<SerialWorker>(8);
  StereoSlam slam(atlas, settings, vocabulary, o, wiring);

  const TimestampNs t0 = frames.front().t_ns;
  const std::size_t inject_at = 200;  // 10 s in: several metres away from the start
  const double drift_m = 0.5, drift_deg = 6.0;
  std::size_t imu_next = 0;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const auto& f = frames[i];
    if (slam.inertial()) slam.add_imu(take_imu_batch(dataset.imu, imu_next, f.t_ns));
    slam.process(f.t_ns, cv::imread(f.left.string(), cv::IMREAD_GRAYSCALE),
                 cv::imread(f.right.string(), cv::IMREAD_GRAYSCALE));
    if (i == inject_at) {
      // A yaw about the current position plus a shift: what odometry drift looks like.
      const auto map = atlas.active_map();
      const Eigen::Vector3d pivot = slam.trajectory().back().T_w_b.t;
      const Eigen::Quaterniond yaw(Eigen::AngleAxisd(drift_deg * M_PI / 180.0, Eigen::Vector3d::UnitZ()));
      const Pose3 delta = Pose3(Eigen::Quaterniond::Identity(), pivot + Eigen::Vector3d(drift_m, 0.0, 0.0)) *
                          Pose3(yaw, Eigen::Vector3d::Zero()) * Pose3(Eigen::Quaterniond::Identity(), -pivot);
      inject_drift(*map, t0 + 3'000'000'000, delta);
    }
  }
  slam.finish();
  const SlamStats stats = slam.stats();
  ASSERT_TRUE(stats.loop_closing);
  ASSERT_GE(stats.loop.loops.size(), 1u) << "the revisit was not recognised";
  const ClosedLoop& loop = stats.loop.loops.front();
  std::printf(
      "loop: keyframe %llu (%.1f s) with %llu (%.1f s), %d matches, correction %.3f m / %.2f deg in %.1f ms "
      "(essential graph %zu edges, %.1f ms); global BA runs %zu\n",
      static_cast<unsigned long long>(loop.current), (loop.current_t_ns - t0) * 1e-9,
      static_cast<unsigned long long>(loop.matched), (loop.matched_t_ns - t0) * 1e-9, loop.matches,
      loop.correction.correction_m, loop.correction.correction_deg, loop.correction.total_ms,
      loop.correction.graph_edges, loop.correction.graph_ms, stats.loop.global_adjustments.size());
  // The loop ties the revisit to the start, and undoes about the injected drift.
  EXPECT_LT(loop.matched_t_ns, t0 + 3'000'000'000);
  EXPECT_GT(loop.correction.correction_m, 0.5 * drift_m);
  EXPECT_LT(loop.correction.correction_m, 3.0 * drift_m);
  EXPECT_EQ(stats.maps, 1u);
  EXPECT_EQ(stats.tracked, stats.frames);

  // An inertial map is corrected in yaw and translation only, and its global
  // BA keeps the IMU terms of its chain.
  EXPECT_EQ(loop.correction.four_dof, slam.inertial());
  ASSERT_GE(stats.loop.global_adjustments.size(), 1u);
  const GlobalAdjustmentRun& global = stats.loop.global_adjustments.front();
  if (!global.interrupted) {
    EXPECT_EQ(global.inertial_edges > 0, slam.inertial());
  }

  const EvalResult eval = evaluate_trajectory(as_trajectory(slam.trajectory()), gt);
  std::printf("ATE after loop closing %.4f m over %zu poses\n", eval.ate.rmse, eval.ate.count);
  EXPECT_LT(eval.ate.rmse, max_ate);
}

TEST(LoopClosing, InjectedDriftIsDetectedAndCorrectedOnRevisit) {
  injected_drift_case("stereo.yaml", 0.012);  // measured 0.0058 m
}

TEST(LoopClosing, AnInertialMapIsCorrectedInYawAndTranslation) {
  injected_drift_case("stereo_inertial.yaml", 0.008);  // measured 0.0040 m
}

}  // namespace
}  // namespace orbatlas
