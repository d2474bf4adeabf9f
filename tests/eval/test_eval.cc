// Trajectory evaluation: cases whose ATE / RPE / scale are known analytically,
// association with interpolation, and ORB-SLAM3's real MH_01 output.
#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <numbers>

#include "core/common/data_paths.h"
#include "core/common/error.h"
#include "core/eval/evaluate.h"
#include "core/eval/live_pose_jumps.h"
#include "core/eval/trajectory_plot.h"
#include "core/geometry/so3.h"
#include "core/io/tum_trajectory.h"

namespace orbatlas {
namespace {

constexpr TimestampNs kT0 = 1403636580838560000;
constexpr TimestampNs kMs = 1'000'000;

// A smooth 3D trajectory with varying orientation, 20 Hz over 20 s.
Trajectory make_wavy_trajectory() {
  Trajectory out;
  for (int i = 0; i <= 400; ++i) {
    const double t = 0.05 * i;
    const Eigen::Vector3d p(2.0 * std::cos(0.3 * t), 1.5 * std::sin(0.5 * t), 1.0 + 0.3 * std::sin(0.2 * t));
    const Eigen::Quaterniond q = so3_exp(Eigen::Vector3d(0.1 * std::sin(t), 0.2 * std::cos(0.7 * t), 0.3 * t));
    out.push_back({kT0 + i * 50 * kMs, Pose3(q, p)});
  }
  return out;
}

Pose3 known_transform() { return Pose3(so3_exp(Eigen::Vector3d(0.3, -1.2, 2.0)), Eigen::Vector3d(5.0, -3.0, 0.7)); }

Trajectory transformed(const Trajectory& in, const Pose3& T) {
  Trajectory out = in;
  for (StampedPose& s : out) s.pose = T * s.pose;
  return out;
}

EvalResult eval(const Trajectory& est, const Trajectory& gt, AlignMode mode) {
  EvalOptions options;
  options.align = mode;
  return evaluate_trajectory(est, gt, options);
}

TEST(Alignment, ParsesModes) {
  EXPECT_EQ(parse_align_mode("se3"), AlignMode::kSe3);
  EXPECT_EQ(parse_align_mode("sim3"), AlignMode::kSim3);
  EXPECT_EQ(parse_align_mode("none"), AlignMode::kNone);
  EXPECT_FALSE(parse_align_mode("SE3").has_value());
  EXPECT_STREQ(align_mode_name(AlignMode::kSim3), "sim3");
}

TEST(Eval, ConstantOffsetIsTheAteWithoutAlignmentAndVanishesWithSe3) {
  const Trajectory gt = make_wavy_trajectory();
  const Eigen::Vector3d offset(0.03, -0.04, 0.0);  // |offset| = 0.05
  Trajectory est = gt;
  for (StampedPose& s : est) s.pose.t += offset;

  const EvalResult none = eval(est, gt, AlignMode::kNone);
  EXPECT_NEAR(none.ate.rmse, 0.05, 1e-12);
  EXPECT_NEAR(none.ate.mean, 0.05, 1e-12);
  EXPECT_NEAR(none.ate.median, 0.05, 1e-12);
  EXPECT_NEAR(none.ate.max, 0.05, 1e-12);
  EXPECT_EQ(none.alignment.scale, 1.0);
  EXPECT_NEAR(none.rpe.trans_rmse_m, 0.0, 1e-12);  // a world offset does not change relative motion
  EXPECT_EQ(none.matched, gt.size());
  EXPECT_EQ(none.est_poses, gt.size());
  EXPECT_EQ(none.gt_poses, gt.size());

  const EvalResult se3 = eval(est, gt, AlignMode::kSe3);
  EXPECT_LT(se3.ate.rmse, 1e-9);
  EXPECT_LT((se3.alignment.translation + offset).norm(), 1e-9);
  EXPECT_LT(rotation_angle(se3.alignment.rotation), 1e-9);
}

TEST(Eval, Se3AlignmentUndoesAKnownTransform) {
  const Trajectory gt = make_wavy_trajectory();
  const Pose3 T = known_transform();
  const Trajectory est = transformed(gt, T);

  const EvalResult se3 = eval(est, gt, AlignMode::kSe3);
  EXPECT_LT(se3.ate.max, 1e-9);
  EXPECT_EQ(se3.alignment.scale, 1.0);
  const Pose3 recovered(se3.alignment.rotation, se3.alignment.translation);
  const Pose3 should_be_identity = recovered * T;
  EXPECT_LT(should_be_identity.t.norm(), 1e-9);
  EXPECT_LT(rotation_angle(should_be_identity.q), 1e-9);

  // Without alignment the error stays; relative motion is unaffected either way.
  const EvalResult none = eval(est, gt, AlignMode::kNone);
  EXPECT_GT(none.ate.rmse, 1.0);
  for (const EvalResult* r : {&se3, &none}) {
    EXPECT_LT(r->rpe.trans_rmse_m, 1e-9);  // RPE of a perfect estimate is 0
    EXPECT_LT(r->rpe.rot_rmse_deg, 1e-7);
    EXPECT_EQ(r->rpe.pairs, 401u - 20u);  // every pose with one 1 s later
  }
}

TEST(Eval, Sim3RecoversAKnownScale) {
  const Trajectory gt = make_wavy_trajectory();
  const Pose3 T = known_transform();
  Trajectory est = gt;
  for (StampedPose& s : est) {
    s.pose.t /= 2.5;  // a monocular estimate at 1/2.5 of the true scale
    s.pose = T * s.pose;
  }
  const EvalResult sim3 = eval(est, gt, AlignMode::kSim3);
  EXPECT_NEAR(sim3.alignment.scale, 2.5, 1e-9);
  EXPECT_LT(sim3.ate.max, 1e-9);
  EXPECT_LT(sim3.rpe.trans_rmse_m, 1e-9);  // RPE uses the sim3 scale
  EXPECT_LT(sim3.rpe.rot_rmse_deg, 1e-7);

  const EvalResult se3 = eval(est, gt, AlignMode::kSe3);
  EXPECT_EQ(se3.alignment.scale, 1.0);
  EXPECT_GT(se3.ate.rmse, 0.1);
  EXPECT_GT(se3.rpe.trans_rmse_m, 0.1);
}

// 16 poses on two horizontal rings (z = +-h), each displaced by d along z with
// alternating sign: the displacements have zero mean and no cross-covariance with
// the positions, so the optimal rigid alignment is exactly the identity (or, for an
// estimate in another frame, exactly that frame's transform), and every pose keeps
// an error of exactly d.
TEST(Eval, KnownNoiseSurvivesSe3Alignment) {
  const double radius = 3.0, h = 0.5, d = 0.02;
  Trajectory gt, noisy;
  for (int i = 0; i < 16; ++i) {
    const int k = i % 8;
    const double a = 2.0 * std::numbers::pi * k / 8.0;
    const Eigen::Vector3d p(radius * std::cos(a), radius * std::sin(a), i < 8 ? -h : h);
    const Pose3 pose(so3_exp(Eigen::Vector3d(0, 0, a)), p);
    const TimestampNs t = kT0 + i * 100 * kMs;
    gt.push_back({t, pose});
    noisy.push_back({t, Pose3(pose.q, p + Eigen::Vector3d(0, 0, k % 2 == 0 ? d : -d))});
  }
  const Trajectory est = transformed(noisy, known_transform());

  const EvalResult se3 = eval(est, gt, AlignMode::kSe3);
  EXPECT_NEAR(se3.ate.rmse, d, 1e-12);
  EXPECT_NEAR(se3.ate.mean, d, 1e-12);
  EXPECT_NEAR(se3.ate.median, d, 1e-12);
  EXPECT_NEAR(se3.ate.max, d, 1e-12);
  EXPECT_EQ(se3.ate.count, 16u);

  const EvalResult none = eval(noisy, gt, AlignMode::kNone);
  EXPECT_NEAR(none.ate.rmse, d, 1e-15);
  EXPECT_NEAR(none.ate.max, d, 1e-15);
}

// Constant-speed circle (r = 2 m, 0.5 rad/s, heading along the motion); the
// estimate moves 10% too far: over 1 s every relative motion is off by exactly
// 0.1 times the 1 s chord, 2 r sin(0.25).
TEST(Eval, RpeOfAScaleErrorIsKnown) {
  Trajectory gt, est;
  for (int i = 0; i <= 200; ++i) {
    const double t = 0.05 * i, a = 0.5 * t;
    const Eigen::Vector3d p(2.0 * std::cos(a), 2.0 * std::sin(a), 1.0);
    const Eigen::Quaterniond q = so3_exp(Eigen::Vector3d(0, 0, a + std::numbers::pi / 2));
    gt.push_back({kT0 + i * 50 * kMs, Pose3(q, p)});
    est.push_back({kT0 + i * 50 * kMs, Pose3(q, 1.1 * p)});
  }
  const double chord = 2.0 * 2.0 * std::sin(0.25);
  const EvalResult none = eval(est, gt, AlignMode::kNone);
  EXPECT_EQ(none.rpe.pairs, 181u);
  EXPECT_NEAR(none.rpe.trans_rmse_m, 0.1 * chord, 1e-12);
  EXPECT_NEAR(none.rpe.rot_rmse_deg, 0.0, 1e-7);

  const EvalResult sim3 = eval(est, gt, AlignMode::kSim3);
  EXPECT_NEAR(sim3.alignment.scale, 1.0 / 1.1, 1e-12);
  EXPECT_LT(sim3.rpe.trans_rmse_m, 1e-12);
  EXPECT_LT(sim3.ate.max, 1e-9);
}

// Analytic motion whose interpolation is exact: linear position, constant-rate
// rotation about a fixed axis (slerp).
Pose3 analytic_pose(TimestampNs t) {
  const double s = ns_to_s(t - kT0);
  return Pose3(so3_exp(0.4 * s * Eigen::Vector3d(1, 2, 2) / 3.0) * Eigen::Quaterniond(0.5, 0.5, -0.5, 0.5),
               Eigen::Vector3d(1.0 + 0.8 * s, -2.0 + 0.3 * s, 0.5 - 0.1 * s));
}

TEST(Eval, InterpolatesA200HzGroundTruthAt20HzEstimates) {
  Trajectory gt;
  for (int i = 0; i <= 2000; ++i) {  // 10 s at 200 Hz, with a 0.5 s hole after 4 s
    const TimestampNs t = kT0 + i * 5 * kMs;
    if (t > kT0 + 4000 * kMs && t < kT0 + 4500 * kMs) continue;
    gt.push_back({t, analytic_pose(t)});
  }
  Trajectory est;
  const Pose3 T = known_transform();
  for (int k = -10; k <= 200; ++k) {  // midway between GT samples, from 0.5 s before to just after
    const TimestampNs t = kT0 + 2500 * 1000 + k * 50 * kMs;
    est.push_back({t, T * analytic_pose(t)});
  }

  const Association a = associate(est, gt);
  EXPECT_EQ(a.pairs.size(), 190u);  // 10 before, 1 after, 10 in the hole are unmatched
  EXPECT_EQ(a.unmatched, 21u);
  for (const PosePair& p : a.pairs) {
    const Pose3 want = analytic_pose(p.t_ns);
    EXPECT_LT((p.ground_truth.t - want.t).norm(), 1e-9);
    EXPECT_LT(rotation_distance(p.ground_truth, want), 1e-9);
  }

  const EvalResult r = eval(est, gt, AlignMode::kSe3);
  EXPECT_EQ(r.matched, 190u);
  EXPECT_EQ(r.est_poses, 211u);
  EXPECT_EQ(r.gt_poses, gt.size());
  EXPECT_LT(r.ate.max, 1e-9);
  EXPECT_LT(r.rpe.trans_rmse_m, 1e-9);
  EXPECT_GT(r.rpe.pairs, 100u);

  // A larger allowed gap interpolates across the hole as well.
  EvalOptions wide;
  wide.association.max_gap_ns = 600 * kMs;
  EXPECT_EQ(evaluate_trajectory(est, gt, wide).matched, 200u);
}

TEST(Eval, NearbyGroundTruthSampleIsUsedExactly) {
  Trajectory gt;
  for (int i = 0; i < 10; ++i)
    gt.push_back({kT0 + i * 5 * kMs, Pose3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(i * i, 0, 0))});
  const Trajectory est = {{kT0 + 5 * kMs + 500, Pose3()}, {kT0 + 10 * kMs - 999, Pose3()}, {kT0 + 12 * kMs, Pose3()}};
  const Association a = associate(est, gt);
  ASSERT_EQ(a.pairs.size(), 3u);
  EXPECT_EQ(a.pairs[0].ground_truth.t.x(), 1.0);
  EXPECT_EQ(a.pairs[1].ground_truth.t.x(), 4.0);
  EXPECT_NEAR(a.pairs[2].ground_truth.t.x(), 4.0 + 0.4 * 5.0, 1e-12);  // interpolated
}

TEST(Eval, TooFewMatchesIsAClearError) {
  const Trajectory gt = make_wavy_trajectory();
  Trajectory est(gt.begin(), gt.begin() + 2);
  try {
    eval(est, gt, AlignMode::kSe3);
    FAIL() << "expected an Error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("only 2 of 2"), std::string::npos) << e.what();
  }
  for (StampedPose& s : est) s.t_ns += 3600 * kNsPerSecond * 1000LL;  // disjoint in time
  est.push_back({est.back().t_ns + 1, Pose3()});
  EXPECT_THROW(eval(est, gt, AlignMode::kNone), Error);
}

TEST(Eval, ErrorStats) {
  const ErrorStats s = error_stats({3.0, 1.0, 4.0, 2.0});
  EXPECT_DOUBLE_EQ(s.mean, 2.5);
  EXPECT_DOUBLE_EQ(s.median, 2.5);
  EXPECT_DOUBLE_EQ(s.max, 4.0);
  EXPECT_DOUBLE_EQ(s.rmse, std::sqrt(30.0 / 4.0));
  EXPECT_DOUBLE_EQ(error_stats({5.0, 1.0, 2.0}).median, 2.0);
  EXPECT_EQ(error_stats({}).count, 0u);
}

TEST(Eval, WritesAPlot) {
  const Trajectory gt = make_wavy_trajectory();
  TrajectoryPlot plot;
  plot.title = "test plot";
  plot.ground_truth.emplace_back();
  plot.estimates.push_back({"estimate", {}});
  for (const auto& s : gt) {
    plot.ground_truth.back().push_back(s.pose.t);
    plot.estimates.back().points.push_back(s.pose.t + Eigen::Vector3d(0.05, 0, 0));
  }
  const auto png = std::filesystem::temp_directory_path() / ("orbatlas_eval_plot_" + std::to_string(getpid()) + ".png");
  write_trajectory_plot(png, plot);
  EXPECT_GT(std::filesystem::file_size(png), 1000u);
  std::filesystem::remove(png);
  EXPECT_THROW(write_trajectory_plot("/nonexistent-dir/x.png", plot), Error);
}

// Two sessions are two lines: nothing is drawn along the segment from the end
// of the first to the start of the second (the demo's joint plot drew that
// segment across the hall), each line has its own colour, and the ground truth
// is dashed (grey, with gaps along it).
TEST(Eval, APlotNeverJoinsTwoTrajectories) {
  TrajectoryPlot plot;
  plot.title = "two sessions";
  std::vector<Eigen::Vector3d> a, b;
  for (int i = 0; i <= 100; ++i) {
    a.emplace_back(0.01 * i, 0.0, 0.0);        // (0, 0) -> (1, 0)
    b.emplace_back(1.0 - 0.01 * i, 5.0, 0.0);  // (1, 5) -> (0, 5)
  }
  plot.estimates = {{"session 1", a}, {"session 2", b}};
  plot.ground_truth = {a, b};
  const auto png = std::filesystem::temp_directory_path() / ("orbatlas_two_lines_" + std::to_string(getpid()) + ".png");
  write_trajectory_plot(png, plot);
  const cv::Mat img = cv::imread(png.string(), cv::IMREAD_COLOR);
  std::filesystem::remove(png);
  ASSERT_FALSE(img.empty());
  // The data is centred in the axes with one scale for both axes: metres -> pixels.
  const PlotArea area = trajectory_plot_area(plot.width_px, plot.height_px);
  const double span_x = 1.0, span_y = 5.0, pad = 0.05 * 5.0;
  const double px_per_m = std::min(area.width / (span_x + 2 * pad), area.height / (span_y + 2 * pad));
  const auto to_px = [&](double x, double y) {
    return cv::Point(static_cast<int>(std::lround(area.x + area.width / 2.0 + (x - 0.5) * px_per_m)),
                     static_cast<int>(std::lround(area.y + area.height / 2.0 - (y - 2.5) * px_per_m)));
  };
  const auto colour_at = [&](cv::Point p) {
    // The most saturated pixel in a 5x5 window (a line is 2 px wide, anti-aliased).
    cv::Vec3b best(255, 255, 255);
    int best_chroma = -1;
    for (int dy = -2; dy <= 2; ++dy)
      for (int dx = -2; dx <= 2; ++dx) {
        const cv::Vec3b c = img.at<cv::Vec3b>(p.y + dy, p.x + dx);
        const int chroma = std::max({c[0], c[1], c[2]}) - std::min({c[0], c[1], c[2]});
        if (chroma > best_chroma) {
          best_chroma = chroma;
          best = c;
        }
      }
    return std::pair{best, best_chroma};
  };
  // Along the segment joining the first line's end (1, 0) to the second's start
  // (1, 5), away from both lines: no colour.
  for (double y = 0.5; y <= 4.5; y += 0.25) {
    EXPECT_LT(colour_at(to_px(1.0, y)).second, 40) << "a line joins the sessions at y " << y;
    EXPECT_LT(colour_at(to_px(0.5, y)).second, 40) << "a line crosses between the sessions at y " << y;
  }
  // Each session is drawn, in its own colour (red, then blue).
  const auto [first, first_chroma] = colour_at(to_px(0.5, 0.0));
  const auto [second, second_chroma] = colour_at(to_px(0.5, 5.0));
  EXPECT_GT(first_chroma, 100);
  EXPECT_GT(second_chroma, 100);
  EXPECT_GT(first[2], first[0]) << "the first session is red";
  EXPECT_GT(second[0], second[2]) << "the second session is blue";
}

// ORB-SLAM3 v1.0 monocular-inertial on the real MH_01 (shipped) against its real
// ground truth: the published figure is a few centimetres.
TEST(Eval, OrbSlam3OnRealMh01IsPlausible) {
  const auto dir = shipped_data_dir() / "euroc";
  const Trajectory gt = read_any_ground_truth(dir / "groundtruth" / "MH_01_easy.txt.gz");
  const Trajectory est = read_tum_trajectory(dir / "peer_trajectories" / "orbslam3_MH01_monoi_frames.txt.gz");
  const EvalResult se3 = eval(est, gt, AlignMode::kSe3);
  const EvalResult sim3 = eval(est, gt, AlignMode::kSim3);
  EXPECT_GT(se3.matched, 3500u);
  for (const EvalResult* r : {&se3, &sim3}) {
    EXPECT_GT(r->ate.rmse, 0.01);
    EXPECT_LT(r->ate.rmse, 0.08);
  }
  EXPECT_LE(sim3.ate.rmse, se3.ate.rmse);  // sim3 has one more degree of freedom
  EXPECT_NEAR(sim3.alignment.scale, 1.0, 0.05);
}

// Coverage: a run that tracks every frame covers the span; one that loses the
// second half covers half of it, however clean its ATE is; a dropped frame
// here and there does not count as lost; several sessions' spans add up.
TEST(Eval, CoverageIsTheFractionOfTheSpanTracked) {
  const Trajectory gt = make_wavy_trajectory();  // 20 s at 20 Hz
  const EvalResult full = eval(gt, gt, AlignMode::kSe3);
  EXPECT_NEAR(full.coverage.fraction, 1.0, 1e-9);
  EXPECT_NEAR(full.coverage.span_s, 20.0, 1e-9);

  Trajectory first_half(gt.begin(), gt.begin() + 201);  // 0 .. 10 s
  const EvalResult half = eval(first_half, gt, AlignMode::kSe3);
  EXPECT_NEAR(half.ate.rmse, 0.0, 1e-9);           // clean where it tracked...
  EXPECT_NEAR(half.coverage.fraction, 0.5, 1e-9);  // ...but only half of the time

  Trajectory dropped;  // every third frame missing: still tracking
  for (std::size_t i = 0; i < gt.size(); ++i)
    if (i % 3 != 1 || i + 1 == gt.size()) dropped.push_back(gt[i]);
  EXPECT_NEAR(eval(dropped, gt, AlignMode::kSe3).coverage.fraction, 1.0, 1e-9);

  Trajectory gap = first_half;  // lost from 10 s to 15 s
  gap.insert(gap.end(), gt.begin() + 300, gt.end());
  EXPECT_NEAR(eval(gap, gt, AlignMode::kSe3).coverage.fraction, 0.75, 1e-9);

  // Two sessions' spans: 0..10 s fully, 15..20 s not at all.
  const std::vector<std::pair<TimestampNs, TimestampNs>> spans = {{gt[0].t_ns, gt[200].t_ns},
                                                                  {gt[300].t_ns, gt[400].t_ns}};
  const Coverage two = trajectory_coverage(first_half, spans);
  EXPECT_NEAR(two.span_s, 15.0, 1e-9);
  EXPECT_NEAR(two.fraction, 10.0 / 15.0, 1e-9);
  EXPECT_EQ(trajectory_coverage({}, spans).fraction, 0.0);
}

// KITTI's relative errors against exact answers: a path of 1 m steps along x;
// an estimate 1 % too long errs by 1 % on every segment, one that turns by
// 0.01 rad per metre errs by that much per metre of segment.
TEST(SegmentErrors, MatchExactDriftsOnEverySegment) {
  std::vector<PosePair> pairs;
  for (int i = 0; i <= 300; ++i) {
    PosePair p;
    p.t_ns = i * 100'000'000LL;
    p.ground_truth = Pose3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(i, 0, 0));
    p.estimate = Pose3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(1.01 * i, 0, 0));
    pairs.push_back(p);
  }
  EXPECT_NEAR(ground_truth_path_length(pairs), 300.0, 1e-9);
  const KittiErrors longer = kitti_relative_errors(pairs, 1.0, {100, 200, 400});
  ASSERT_EQ(longer.by_length.size(), 3u);
  // From every 10th pose, those that have 100 (200) m left: 21 (11); none for 400 m.
  EXPECT_EQ(longer.by_length[0].segments, 21u);
  EXPECT_EQ(longer.by_length[1].segments, 11u);
  EXPECT_EQ(longer.by_length[2].segments, 0u);
  EXPECT_EQ(longer.segments, 32u);
  EXPECT_NEAR(longer.trans_percent, 1.0, 1e-9);
  EXPECT_NEAR(longer.by_length[1].trans_percent, 1.0, 1e-9);
  EXPECT_NEAR(longer.rot_deg_per_m, 0.0, 1e-9);
  // The sim3 scale undoes the stretch.
  EXPECT_NEAR(kitti_relative_errors(pairs, 1.0 / 1.01, {100}).trans_percent, 0.0, 1e-9);

  // A yaw drift of 0.01 rad per metre of travel (the positions exact).
  for (std::size_t i = 0; i < pairs.size(); ++i)
    pairs[i].estimate =
        Pose3(Eigen::Quaterniond(Eigen::AngleAxisd(0.01 * static_cast<double>(i), Eigen::Vector3d::UnitZ())),
              pairs[i].ground_truth.t);
  const KittiErrors turned = kitti_relative_errors(pairs, 1.0, {100});
  EXPECT_NEAR(turned.rot_deg_per_m, 0.01 * 180.0 / std::numbers::pi, 1e-9);

  // Short paths get lengths that fit them; long ones the benchmark's.
  EXPECT_EQ(kitti_lengths_for_path(60.0), (std::vector<double>{6, 12, 18, 24, 30, 36, 42, 48}));
  EXPECT_EQ(kitti_lengths_for_path(350.0), (std::vector<double>{100, 200, 300}));
  EXPECT_THROW(kitti_relative_errors(pairs, 1.0, {0.0}), Error);
  EXPECT_THROW(kitti_relative_errors(pairs, 1.0, {100}, 0), Error);
}

// The live pose's jump at a correction: the distance from where the two
// frames before predicted it (constant velocity), only when the maps were
// edited or the map changed since the frame before; a lost frame starts afresh.
TEST(LivePoseJumps, MeasureTheMoveFromThePredictedPoseAtCorrectionsOnly) {
  LivePoseJumps jumps;
  EXPECT_FALSE(jumps.add({0.0, 0, 0}, 1, 5).has_value());  // the first frame: nothing to compare
  EXPECT_FALSE(jumps.add({0.1, 0, 0}, 1, 5).has_value());  // no correction
  EXPECT_FALSE(jumps.add({0.2, 0, 0}, 1, 5).has_value());
  // The maps were edited: predicted 0.3, given 0.3 + (0, 0.04, 0.03).
  const auto jump = jumps.add({0.3, 0.04, 0.03}, 1, 6);
  ASSERT_TRUE(jump.has_value());
  EXPECT_NEAR(*jump, 0.05, 1e-12);
  EXPECT_FALSE(jumps.add({0.4, 0.04, 0.03}, 1, 6).has_value());
  // A merge: another map (its frame), the same edits count.
  const auto merged = jumps.add({2.5, 0.04, 0.03}, 2, 6);
  ASSERT_TRUE(merged.has_value());
  EXPECT_NEAR(*merged, 2.0, 1e-12);  // predicted 0.5
  // After a lost frame, the first tracked one has nothing to be compared with;
  // the next, one frame before it only: its position.
  jumps.lost();
  EXPECT_FALSE(jumps.add({3.0, 0, 0}, 2, 7).has_value());
  const auto after_one = jumps.add({3.2, 0, 0}, 2, 8);
  ASSERT_TRUE(after_one.has_value());
  EXPECT_NEAR(*after_one, 0.2, 1e-12);
}

}  // namespace
}  // namespace orbatlas
