// Monocular SLAM through the runner: a simulated clip of one camera
// (cam0 of the rendering, config/euroc/mono.yaml) starts its map from two views
// and maps at its own scale; the camera's trajectory, aligned with a
// similarity, follows the ground truth within a small fraction of the path.
// With its IMU (mono_inertial.yaml) the map becomes metric, and its final
// visual-inertial BA runs with its own mapping and with a map server's.
#include <gtest/gtest.h>

#include <iostream>
#include <memory>
#include <opencv2/imgcodecs.hpp>
#include <vector>

#include "core/common/data_paths.h"
#include "core/eval/evaluate.h"
#include "core/io/tum_trajectory.h"
#include "core/pipeline/dataset_runner.h"
#include "core/slam/mapping_workers.h"
#include "core/slam/session_wiring.h"
#include "core/slam/slam_system.h"
#include "core/vocabulary/default_vocabulary.h"
#include "tests/support/slam_test_clip.h"

namespace orbatlas {
namespace {

double path_length(const std::vector<GroundTruthState>& gt, TimestampNs from, TimestampNs to) {
  double length = 0.0;
  const GroundTruthState* last = nullptr;
  for (const auto& s : gt) {
    if (s.t_ns < from || s.t_ns > to) continue;
    if (last) length += (s.T_w_b.t - last->T_w_b.t).norm();
    last = &s;
  }
  return length;
}

TEST(MonoSlam, ASimulatedClipMapsWithinAFractionOfItsPath) {
  const auto clip = test::simulated_clip("MH_01", 50.0, 20.0);  // moving from the start
  test::ClipCleanup cleanup{clip};
  DatasetRunOptions options;
  options.settings = shipped_config_dir() / "euroc" / "mono.yaml";
  options.dataset = clip;
  options.show_progress = false;
  options.slam.synchronous_mapping = true;
  const DatasetRunReport report = run_dataset(options);
  ASSERT_TRUE(report.ate_rmse_m.has_value());
  EXPECT_TRUE(report.ate_sim3);
  ASSERT_FALSE(report.trajectory.empty());
  const EurocDataset dataset = test::stereo_dataset(clip);
  const double path_m =
      path_length(dataset.ground_truth, report.trajectory.front().t_ns, report.trajectory.back().t_ns);
  EXPECT_EQ(report.stats.frames, 401u);
  EXPECT_EQ(report.stats.monocular_starts, 1u);
  EXPECT_EQ(report.stats.maps, 1u);
  // The map starts within the first second, and every frame after is tracked.
  EXPECT_GE(report.stats.tracked, 390u);  // measured 397: the map starts at the fifth frame
  EXPECT_EQ(report.stats.lost, report.stats.frames - report.stats.tracked);
  EXPECT_GT(path_m, 5.0);
  EXPECT_LT(*report.ate_rmse_m, 0.02 * path_m);  // the bound
  EXPECT_LT(*report.ate_rmse_m, 0.015);          // measured 0.0075 m over 12.2 m
}

// Monocular-inertial: the map starts from two views at an arbitrary scale; the
// inertial initialisation (2 s of keyframes, scale free) makes it metric, and
// the session goes on in that map. The camera's trajectory then needs no scale
// to meet the ground truth.
TEST(MonoInertialSlam, TheImuGivesTheMapItsMetricScale) {
  const auto clip = test::simulated_clip("MH_01", 50.0, 15.0);
  test::ClipCleanup cleanup{clip};
  DatasetRunOptions options;
  options.settings = shipped_config_dir() / "euroc" / "mono_inertial.yaml";
  options.dataset = clip;
  options.show_progress = false;
  options.slam.synchronous_mapping = true;
  const DatasetRunReport report = run_dataset(options);
  ASSERT_TRUE(report.ate_rmse_m.has_value());
  EXPECT_FALSE(report.ate_sim3);  // metric: SE3
  ASSERT_TRUE(report.stats.imu_initialized_at_s.has_value());
  const EurocDataset dataset = test::stereo_dataset(clip);
  EvalOptions sim3;
  sim3.align = AlignMode::kSim3;
  sim3.estimate_T_b_x = dataset.cameras[0].calibration.T_b_c;
  const EvalResult with_scale =
      evaluate_trajectory(report.trajectory, from_ground_truth_states(dataset.ground_truth), sim3);
  EXPECT_EQ(report.stats.maps, 1u);
  EXPECT_GE(report.stats.tracked, 290u);               // of 301; the map starts at the fifth frame
  EXPECT_LT(*report.stats.imu_initialized_at_s, 3.5);  // measured 2.75 s (ten keyframes)
  // On a clip this short the figures follow the run's numerics more than its
  // method: the same run with its map started turned about the vertical or tilted
  // ended 0.015-0.09 m and up to 2.2 % off in scale (19 orientations, before
  // keypoints were placed at their pixels' centres; 0.024 m and 0.5 % unturned).
  // Measured now: 0.069 m, 1.35 %. The bounds hold the spread.
  std::cout << "monocular-inertial clip: ATE " << *report.ate_rmse_m << " m, scale " << with_scale.alignment.scale
            << "\n";
  EXPECT_LT(std::abs(with_scale.alignment.scale - 1.0), 0.03) << with_scale.alignment.scale;
  EXPECT_LT(*report.ate_rmse_m, 0.12);
  // Its scale comes from the IMU alone: the session ends with one more full
  // visual-inertial BA (Orbatlas.LoopClosing.FinalBaForImuScale, on).
  EXPECT_GT(report.stats.final_ba_keyframes, 10u);
}

// The same session with the mapping of a map server (shared, SessionWiring):
// its map gets the final visual-inertial BA from the loop closer when the
// session finishes (LoopCloserOptions::stream_end_imu_scale), with its IMU
// terms, though no other session mapped there.
TEST(MonoInertialSlam, ASharedMappingsSessionGetsTheFinalBaAtItsFinish) {
  const auto clip = test::simulated_clip("MH_01", 50.0, 15.0);
  test::ClipCleanup cleanup{clip};
  const EurocDataset dataset = test::stereo_dataset(clip);
  const SlamSettings settings =
      read_settings(shipped_config_dir() / "euroc" / "mono_inertial.yaml", SensorType::kMonocularInertial);
  const Vocabulary vocabulary = Vocabulary::load(default_vocabulary_path());
  Atlas atlas;
  std::shared_ptr<MappingWorkers> mapping;
  SessionWiring wiring;
  wiring.mapping = [&](const FrameCamera& cam, const MappingWorkersOptions& options) {
    if (!mapping) mapping = std::make_shared<MappingWorkers>(atlas, cam, options);
    return mapping;
  };
  SlamSystemOptions o;
  o.synchronous_mapping = true;
  o.shared_map_finish_wait_s = 60.0;  // as the server's --finish-refinement-wait
  SlamSystem slam(atlas, settings, vocabulary, o, wiring);
  std::size_t next_imu = 0;
  for (const auto& f : test::stereo_frames(clip)) {
    std::vector<ImuSample> batch;
    while (next_imu < dataset.imu.size() && dataset.imu[next_imu].t_ns <= f.t_ns)
      batch.push_back(dataset.imu[next_imu++]);
    if (next_imu < dataset.imu.size()) batch.push_back(dataset.imu[next_imu++]);  // the first after the frame
    slam.add_imu(batch);
    slam.process(f.t_ns, cv::imread(f.left.string(), cv::IMREAD_GRAYSCALE), cv::Mat());
  }
  slam.finish();
  const auto end_refinement = slam.take_end_refinement();
  ASSERT_TRUE(end_refinement);
  EXPECT_TRUE(end_refinement());
  const SlamStats stats = slam.stats();
  ASSERT_TRUE(stats.imu_initialized_at_s.has_value());
  EXPECT_EQ(stats.final_ba_keyframes, 0u);  // not the offline one
  std::vector<GlobalAdjustmentRun> at_end;
  for (const auto& g : stats.loop.global_adjustments)
    if (g.cause == GlobalAdjustmentCause::kStreamEnd) at_end.push_back(g);
  ASSERT_EQ(at_end.size(), 1u);
  EXPECT_FALSE(at_end[0].interrupted);
  EXPECT_GT(at_end[0].keyframes, 20u);                           // measured 26
  EXPECT_EQ(at_end[0].inertial_edges, at_end[0].keyframes - 1);  // the whole chain
  // Measured: with FinalBaForImuScale 0 there is none (a map of one session).
}

}  // namespace
}  // namespace orbatlas
