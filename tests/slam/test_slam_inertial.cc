// Visual-inertial SLAM, first stage, through the runner: a
// stereo-inertial config fuses the clip's imu0. Keyframes are linked by the IMU
// preintegrated between them, and after about 2 s of keyframes the map gets its
// inertial initialisation: it is turned so that gravity is -z of its frame, and
// gets the IMU biases, compared with the simulator's truth (the direction of
// gravity in the first frame's body; the synthetic IMU has noise and drifting
// biases). A full visual-inertial BA follows the initialisation and the
// refinement, and the final global BA (--final-ba) keeps the IMU terms.
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <functional>
#include <iostream>
#include <sstream>

#include "core/common/data_paths.h"
#include "core/eval/gap_error.h"
#include "core/pipeline/dataset_runner.h"
#include "wire/run_report_json.h"
#include "tests/support/slam_test_clip.h"

namespace orbatlas {
namespace {

// The shipped stereo-inertial config on a clip, deterministic: the
// initialisation sees every keyframe as it comes.
DatasetRunReport run_stereo_inertial(const std::filesystem::path& clip,
                                     std::optional<std::pair<double, double>> black_out_s = std::nullopt,
                                     bool final_ba = false, bool consistency = true) {
  DatasetRunOptions options;
  options.slam.mapper.inertial_consistency.enabled = consistency;
  options.slam.final_global_ba = final_ba;
  options.black_out_s = black_out_s;
  options.settings = shipped_config_dir() / "euroc" / "stereo_inertial.yaml";
  options.dataset = clip;
  options.show_progress = false;
  options.slam.synchronous_mapping = true;
  return run_dataset(options);
}

// Rewrites a clip's imu0/data.csv: `edit` gets each sample's time from the
// first (s), its fields, and the accelerometer y of the sample at 3.0 s (to
// hold an axis stuck); false drops the sample.
void rewrite_imu(const std::filesystem::path& clip,
                 const std::function<bool(double, std::vector<std::string>&, const std::string&)>& edit) {
  const auto csv = clip / "mav0" / "imu0" / "data.csv";
  std::vector<std::string> lines;
  {
    std::ifstream in(csv);
    for (std::string line; std::getline(in, line);) lines.push_back(line);
  }
  ASSERT_GT(lines.size(), 1000u);
  const TimestampNs t0 = std::stoll(lines[1].substr(0, lines[1].find(',')));
  std::ofstream out(csv);
  std::string stuck_value;
  for (const auto& line : lines) {
    if (line.empty() || line[0] == '#') {
      out << line << "\n";
      continue;
    }
    std::vector<std::string> f;
    std::stringstream fields(line);
    for (std::string x; std::getline(fields, x, ',');) f.push_back(x);
    const double s = ns_to_s(std::stoll(f[0]) - t0);
    if (s >= 3.0 && stuck_value.empty()) stuck_value = f[5];
    if (!edit(s, f, stuck_value)) continue;
    for (std::size_t i = 0; i < f.size(); ++i) out << (i ? "," : "") << f[i];
    out << "\n";
  }
}

TEST(InertialSlam, AStereoInertialRunInitialisesItsMapsGravityAndBiases) {
  const auto clip = test::simulated_clip("MH_01", 40.0, 8.0);
  test::ClipCleanup cleanup{clip};
  const DatasetRunReport report = run_stereo_inertial(clip, std::nullopt, /*final_ba=*/true);
  const SlamStats& s = report.stats;
  ASSERT_TRUE(s.inertial);
  EXPECT_EQ(s.tracked, s.frames);
  EXPECT_GT(s.imu_samples, 1500u);  // 200 Hz over 8 s
  EXPECT_EQ(s.imu_uncovered_keyframes, 0u);
  EXPECT_EQ(s.imu_linked_keyframes + 1, s.keyframes_made);  // every keyframe but the map's first
  ASSERT_TRUE(s.imu_initialized_at_s.has_value()) << "no inertial initialisation after 8 s";
  // Every keyframe after the initialisation is placed by visual-inertial BA.
  EXPECT_GT(s.mapping.inertial_bundle_adjustments, 10u);
  // Refined once, 5 s after the initialisation (the 15-s one is past the clip).
  EXPECT_EQ(s.mapping.inertial_refinements, 1u);
  // A full visual-inertial BA after each (ORB-SLAM3's FullInertialBA), run
  // by the loop closer in the background, and the final global BA
  // (--final-ba) keeps the IMU terms of the chain.
  const auto inertial_adjustments =
      std::count_if(s.loop.global_adjustments.begin(), s.loop.global_adjustments.end(), [](const auto& g) {
        return g.cause == GlobalAdjustmentCause::kInertial && !g.interrupted && g.inertial_edges > 0;
      });
  EXPECT_EQ(inertial_adjustments, 2);
  EXPECT_EQ(s.mapping.full_inertial_bundle_adjustments, 0u) << "none on local mapping's thread";
  EXPECT_GT(s.final_ba_keyframes, 0u);
  EXPECT_GT(s.final_ba_inertial_edges, 5u);
  EXPECT_GE(*s.imu_initialized_at_s, 2.0);

  const EurocDataset data = test::stereo_dataset(clip);
  const auto frames = pair_stereo_frames(data);
  Trajectory gt;
  for (const auto& g : data.ground_truth) gt.push_back({g.t_ns, g.T_w_b});
  const auto first = pose_at(gt, frames.front().t_ns, 50'000'000);
  ASSERT_TRUE(first.has_value());
  // The map was turned so that gravity is -z of its frame; the refinement
  // left the frame where it was and tilted the map's gravity by what it found
  // (a fraction of a degree). The first frame's body sees gravity where it
  // truly was (yaw is free: only the direction in the body is compared).
  EXPECT_NEAR(s.imu_gravity_w.norm(), 9.81, 1e-9);
  const double tilt_deg = std::acos(std::clamp(-s.imu_gravity_w.z() / 9.81, -1.0, 1.0)) * 180.0 / M_PI;
  std::cout << "the refinement tilted the map's gravity by " << tilt_deg << " deg\n";
  EXPECT_LT(tilt_deg, 0.08);  // measured 0.036 deg
  ASSERT_FALSE(report.trajectory.empty());
  ASSERT_EQ(report.trajectory.front().t_ns, frames.front().t_ns);
  const Eigen::Vector3d gravity_in_body = report.trajectory.front().pose.q.conjugate() * s.imu_gravity_w;
  const Eigen::Vector3d gravity_true = first->q.conjugate() * Eigen::Vector3d(0.0, 0.0, -9.81);
  const double gravity_deg =
      std::atan2(gravity_in_body.cross(gravity_true).norm(), gravity_in_body.dot(gravity_true)) * 180.0 / M_PI;
  // The true biases at the initialisation.
  const TimestampNs at = frames.front().t_ns + s_to_ns(*s.imu_initialized_at_s);
  const auto truth = std::min_element(data.ground_truth.begin(), data.ground_truth.end(),
                                      [at](const GroundTruthState& a, const GroundTruthState& b) {
                                        return std::llabs(a.t_ns - at) < std::llabs(b.t_ns - at);
                                      });
  const double gyro_error = (s.imu_bias.gyro - truth->gyro_bias).norm();
  EXPECT_LT(gravity_deg, 0.7);  // measured 0.32 deg
  // The map started level (its first frame turned to the gravity its IMU
  // measured), so the initialisation turned it by little and the device's
  // live poses moved by little when it did.
  ASSERT_FALSE(report.live_trajectory.empty());
  const Eigen::Vector3d live_down_body = report.live_trajectory.front().pose.q.conjugate() * Eigen::Vector3d(0, 0, -1);
  const double live_level_deg =
      std::atan2(live_down_body.cross(gravity_true).norm(), live_down_body.dot(gravity_true)) * 180.0 / M_PI;
  std::cout << "level start off by " << live_level_deg << " deg; largest live jump "
            << (report.live_jumps_m.empty() ? 0.0
                                            : *std::max_element(report.live_jumps_m.begin(), report.live_jumps_m.end()))
            << " m\n";
  EXPECT_LT(live_level_deg, 0.7);  // measured 0.35 deg
  ASSERT_FALSE(report.live_jumps_m.empty());
  EXPECT_LT(*std::max_element(report.live_jumps_m.begin(), report.live_jumps_m.end()), 0.003);  // measured 0.0015 m
  EXPECT_LT(gyro_error, 0.0005);  // measured 0.0002 rad/s (true bias 0.016)
  ASSERT_TRUE(report.ate_rmse_m.has_value());
  EXPECT_LT(*report.ate_rmse_m, 0.002);  // measured 0.0009 m
  const nlohmann::json j = to_json(report);
  EXPECT_TRUE(j.contains("imu_initialized_at_s"));
  EXPECT_EQ(j["imu_bias"]["gyro"].size(), 3u);
  // The clean look's IMU has the settings' white noise: the links use the
  // settings' densities, or what was measured a little above them.
  ASSERT_TRUE(s.imu_white_noise.has_value());
  const ImuNoise settings;
  std::cout << "white noise used: " << s.imu_white_noise->gyro / settings.gyro_density << ", "
            << s.imu_white_noise->accel / settings.accel_density << " times the settings'\n";
  EXPECT_GE(s.imu_white_noise->gyro, settings.gyro_density);
  EXPECT_LT(s.imu_white_noise->gyro, 1.18 * settings.gyro_density);
  EXPECT_GE(s.imu_white_noise->accel, settings.accel_density);
  EXPECT_LT(s.imu_white_noise->accel, 1.13 * settings.accel_density);
  EXPECT_EQ(j["imu_white_noise"]["acc"], s.imu_white_noise->accel);
}

TEST(InertialSlam, TheImuCarriesTrackingThroughOneSecondOfBlackFrames) {
  // MH_01 40-48 s with the images black from 4 s to 5 s: the map is inertially
  // initialised at about 2 s; through the gap every frame is tracked by the IMU
  // (no relocalisation, no new map), and the first frame after it is tracked
  // visually again in the same map.
  const auto clip = test::simulated_clip("MH_01", 40.0, 8.0);
  test::ClipCleanup cleanup{clip};
  const DatasetRunReport report = run_stereo_inertial(clip, std::make_pair(4.0, 5.0));
  ASSERT_TRUE(report.black_out.has_value());
  const std::size_t blacked = report.black_out->frames;
  ASSERT_EQ(blacked, 20u);  // 20 Hz
  EXPECT_EQ(report.black_out->by_imu, blacked);
  EXPECT_EQ(report.black_out->frames_to_visual, 0u);
  const SlamStats& s = report.stats;
  ASSERT_TRUE(s.imu_initialized_at_s.has_value());
  EXPECT_EQ(s.frames_tracked_by_imu, blacked);
  EXPECT_EQ(s.tracked + s.frames_tracked_by_imu, s.frames);  // visual again at the first frame after the gap
  EXPECT_EQ(s.maps_started, 1u);
  EXPECT_EQ(s.lost, 0u);
  EXPECT_GT(s.frames_optimized_with_imu, s.frames / 2);

  // The error at the end of the gap, with the trajectory aligned (SE3) on the
  // visually tracked frames (before and after it: a few seconds of nearly
  // straight flight on one side leave the rotation about it loose).
  const EurocDataset data = test::stereo_dataset(clip);
  Trajectory gt;
  for (const auto& g : data.ground_truth) gt.push_back({g.t_ns, g.T_w_b});
  const TimestampNs start = report.trajectory.front().t_ns;
  const auto gap = gap_error(report.trajectory, gt, start + s_to_ns(4.0), start + s_to_ns(5.0));
  ASSERT_TRUE(gap.has_value());
  ASSERT_TRUE(gap->after_m.has_value());
  EXPECT_EQ(report.black_out->error_at_end_m, gap->at_end_m);  // what `orbatlas run --black-out` reports
  const double end_of_gap = gap->at_end_m, after_gap = *gap->after_m, gap_end_s = ns_to_s(gap->end_t_ns - start);
  EXPECT_GT(gap_end_s, 4.9);
  EXPECT_LT(end_of_gap, 0.006);  // measured 0.003 m (0.014 m before visual-inertial BA; the bar: 0.10 m)
  EXPECT_LT(after_gap, 0.006);   // measured 0.003 m
}

TEST(InertialSlam, ASessionFindsTheImusClockOffsetAndUsesIt) {
  // The realistic IMU (the real flights' vibration, biases, noise) 5 ms late
  // against the camera, on 16 s of flight: the session fits the offset every
  // 2 s over the last 10 s of tracked frames.
  sim::ImuErrorModel errors = sim::realistic_imu_errors();
  errors.time_offset_s = 0.005;
  const auto clip = test::simulated_clip("MH_01", 50.0, 16.0, /*depth=*/false, errors, "offset5ms");
  test::ClipCleanup cleanup{clip};
  const DatasetRunReport report = run_stereo_inertial(clip);
  const SlamStats& s = report.stats;
  EXPECT_EQ(s.tracked, s.frames);
  EXPECT_EQ(s.maps_started, 1u);
  ASSERT_TRUE(s.imu_time_offset_ms.has_value()) << "no estimate of the IMU's clock after 16 s";
  ASSERT_TRUE(report.ate_rmse_m.has_value());
  EXPECT_NEAR(*s.imu_time_offset_ms, 5.0, 1.0);  // measured 4.41 ms
  EXPECT_EQ(to_json(report)["imu_time_offset_ms"], *s.imu_time_offset_ms);
  EXPECT_LT(*report.ate_rmse_m, 0.007);  // measured 0.0035 m
  // In flight the vibration makes the samples' differences far above any
  // white noise: the links use the cap, 3 times the settings' densities.
  ASSERT_TRUE(s.imu_white_noise.has_value());
  EXPECT_DOUBLE_EQ(s.imu_white_noise->gyro, 3.0 * ImuNoise{}.gyro_density);
  EXPECT_DOUBLE_EQ(s.imu_white_noise->accel, 3.0 * ImuNoise{}.accel_density);
}

TEST(InertialSlam, ABadImuStreamIsReportedAndVisionCarriesOn) {
  // The clip's IMU with faults a real device shows: two samples not a number
  // (2.5 s), the accelerometer's y axis stuck for 1 s (3-4 s) and 0.3 s
  // missing (5.5 s).
  const auto clip = test::simulated_clip("MH_01", 40.0, 8.0);
  test::ClipCleanup cleanup{clip};
  rewrite_imu(clip, [](double s, std::vector<std::string>& f, const std::string& first_stuck) {
    if (s >= 5.5 && s < 5.8) return false;
    if (s >= 2.5 && s < 2.51) f[1] = "nan";
    if (s >= 3.0 && s < 4.0) f[5] = first_stuck;
    return true;
  });

  const DatasetRunReport report = run_stereo_inertial(clip);
  const SlamStats& s = report.stats;
  const ImuInputHealth& h = s.imu_input;
  EXPECT_EQ(h.non_finite, 2u);
  EXPECT_EQ(h.stuck, 151u);  // 200 samples stuck, the first 49 not yet told
  EXPECT_EQ(h.gaps, 1u);
  EXPECT_NEAR(h.longest_gap_s, 0.305, 0.006);
  ASSERT_EQ(h.warnings.size(), 3u) << to_json(report)["imu_input"].dump();
  const nlohmann::json j = to_json(report);
  EXPECT_EQ(j["imu_input"]["warnings"].size(), 3u);
  EXPECT_EQ(j["imu_input"]["dropped_stuck"], 151u);
  // Vision carries every frame; the IMU is back after each fault.
  EXPECT_EQ(s.tracked, s.frames);
  EXPECT_EQ(s.maps_started, 1u);
  EXPECT_GT(s.imu_uncovered_keyframes, 0u);
  ASSERT_TRUE(s.imu_initialized_at_s.has_value());
  ASSERT_TRUE(report.ate_rmse_m.has_value());
  EXPECT_LT(*report.ate_rmse_m, 0.0025);  // measured 0.0011 m
}

TEST(InertialSlam, AMapWhoseImuDisagreesGoesVisualAndIsInitialisedAgain) {
  // The accelerometer's bias jumps by 0.5 m/s^2 on its y axis 4 s into the
  // clip (2 s after the initialisation): the local BAs' inertial chi2 rises
  // far above a consistent IMU's, the map drops its inertial state, is
  // tracked by vision, and is initialised again with the new bias.
  const auto clip = test::simulated_clip("MH_01", 40.0, 8.0);
  test::ClipCleanup cleanup{clip};
  const auto baseline = run_stereo_inertial(clip);
  rewrite_imu(clip, [](double s, std::vector<std::string>& f, const std::string&) {
    if (s >= 4.0) f[5] = std::to_string(std::stod(f[5]) + 0.5);
    return true;
  });
  const DatasetRunReport report = run_stereo_inertial(clip);
  const DatasetRunReport unchecked = run_stereo_inertial(clip, std::nullopt, false, /*consistency=*/false);
  const SlamStats& s = report.stats;
  ASSERT_TRUE(report.ate_rmse_m.has_value());
  ASSERT_TRUE(baseline.ate_rmse_m.has_value());
  ASSERT_TRUE(unchecked.ate_rmse_m.has_value());
  EXPECT_EQ(unchecked.stats.mapping.inertial_resets, 0u);
  EXPECT_LT(*report.ate_rmse_m, *unchecked.ate_rmse_m);
  EXPECT_EQ(baseline.stats.mapping.inertial_resets, 0u);
  EXPECT_GE(s.mapping.inertial_resets, 1u);
  EXPECT_EQ(s.tracked, s.frames);
  EXPECT_EQ(s.maps_started, 1u);
  ASSERT_TRUE(s.imu_initialized_at_s.has_value()) << "initialised again after the reset";
  EXPECT_GT(*s.imu_initialized_at_s, 4.0);
  EXPECT_LT(*report.ate_rmse_m, 0.009);  // measured 0.0047 m
}

}  // namespace
}  // namespace orbatlas
