// `orbatlas eval`: ATE / RPE of an estimated trajectory against ground truth.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "client/commands.h"
#include "core/common/error.h"
#include "core/eval/evaluate.h"
#include "core/eval/trajectory_plot.h"
#include "core/io/euroc_reader.h"
#include "core/io/kitti_odometry.h"
#include "core/io/tum_trajectory.h"

namespace orbatlas::cli {
namespace {

struct EvalArgs {
  std::vector<std::string> gt;  // several: sessions in one world frame, joined
  std::vector<std::string> est;
  std::string align = "se3";
  std::string est_frame = "body";  // or cam0: the estimate is the camera's (monocular sessions)
  double max_gap_s = 0.1;
  bool json = false;
  std::string plot;
  // KITTI's relative errors over these segment lengths [m]; "auto": the lengths
  // that suit the path. Computed for KITTI ground truth, or when given.
  std::vector<std::string> segments;
};

nlohmann::ordered_json to_json(const EvalResult& r) {
  return {{"ate_rmse_m", r.ate.rmse},          {"ate_mean_m", r.ate.mean},
          {"ate_median_m", r.ate.median},      {"ate_max_m", r.ate.max},
          {"rpe_trans_m", r.rpe.trans_rmse_m}, {"rpe_rot_deg", r.rpe.rot_rmse_deg},
          {"rpe_pairs", r.rpe.pairs},          {"scale", r.alignment.scale},
          {"align", align_mode_name(r.align)}, {"matched", r.matched},
          {"est_poses", r.est_poses},          {"gt_poses", r.gt_poses},
          {"coverage", r.coverage.fraction},   {"covered_s", r.coverage.covered_s},
          {"span_s", r.coverage.span_s}};
}

nlohmann::ordered_json to_json(const KittiErrors& k) {
  nlohmann::ordered_json lengths = nlohmann::ordered_json::array();
  for (const SegmentErrors& s : k.by_length)
    lengths.push_back({{"length_m", s.length_m},
                       {"segments", s.segments},
                       {"trans_percent", s.trans_percent},
                       {"rot_deg_per_m", s.rot_deg_per_m}});
  return {{"trans_percent", k.trans_percent},
          {"rot_deg_per_m", k.rot_deg_per_m},
          {"segments", k.segments},
          {"path_m", k.path_m},
          {"lengths", lengths}};
}

std::string joined(const std::vector<std::string>& paths) {
  std::string out;
  for (const auto& p : paths) out += (out.empty() ? "" : " + ") + p;
  return out;
}

void print_human(const EvalArgs& args, const EvalResult& r) {
  char buf[512];
  std::cout << "orbatlas eval: " << joined(args.est) << "\n  vs ground truth " << joined(args.gt) << "\n";
  std::snprintf(buf, sizeof buf,
                "  alignment      %s, scale %.6f\n"
                "  matched poses  %zu of %zu estimated (ground truth: %zu poses)\n"
                "  coverage       %.3f (%.1f s of %.1f s tracked)\n"
                "  ATE [m]        rmse %.4f  mean %.4f  median %.4f  max %.4f\n"
                "  RPE over 1 s   trans %.4f m  rot %.4f deg  (%zu pairs)\n",
                align_mode_name(r.align), r.alignment.scale, r.matched, r.est_poses, r.gt_poses, r.coverage.fraction,
                r.coverage.covered_s, r.coverage.span_s, r.ate.rmse, r.ate.mean, r.ate.median, r.ate.max,
                r.rpe.trans_rmse_m, r.rpe.rot_rmse_deg, r.rpe.pairs);
  std::cout << buf;
  if (r.segments) {
    const KittiErrors& k = *r.segments;
    std::string lengths;
    for (const SegmentErrors& s : k.by_length)
      lengths += (lengths.empty() ? "" : ", ") + std::to_string(std::lround(s.length_m));
    if (k.segments == 0) {
      std::snprintf(buf, sizeof buf, "  KITTI errors   no segment of %s m fits the %.1f m path (--segments)\n",
                    lengths.c_str(), k.path_m);
    } else {
      std::snprintf(buf, sizeof buf,
                    "  KITTI errors   trans %.3f %%  rot %.5f deg/m  (%zu segments of %s m; path %.1f m)\n",
                    k.trans_percent, k.rot_deg_per_m, k.segments, lengths.c_str(), k.path_m);
    }
    std::cout << buf;
  }
}

// One line per --est file (sessions are never joined in a plot), each with the
// ground truth over its own span (plus 1 s), all under the one alignment.
void write_plot(const EvalArgs& args, const std::vector<Trajectory>& est_parts, const Trajectory& gt,
                const EvalResult& r) {
  TrajectoryPlot plot;
  for (std::size_t i = 0; i < est_parts.size(); ++i) {
    const Trajectory& est = est_parts[i];
    if (est.empty()) continue;
    const TimestampNs from = est.front().t_ns - kNsPerSecond, to = est.back().t_ns + kNsPerSecond;
    std::vector<Eigen::Vector3d> truth;
    for (const StampedPose& s : gt)
      if (s.t_ns >= from && s.t_ns <= to) truth.push_back(s.pose.t);
    if (!truth.empty()) plot.ground_truth.push_back(std::move(truth));
    PlotLine line;
    line.label =
        (est_parts.size() == 1 ? std::string("estimate") : std::filesystem::path(args.est[i]).filename().string()) +
        " (" + align_mode_name(r.align) + ")";
    for (const StampedPose& s : est) line.points.push_back(r.alignment.apply(s.pose.t));
    plot.estimates.push_back(std::move(line));
  }
  char title[256];
  std::snprintf(title, sizeof title, "%s   ATE RMSE %.4f m (%s)   %zu poses",
                (args.est.size() == 1 ? std::filesystem::path(args.est.front()).filename().string()
                                      : std::to_string(args.est.size()) + " trajectories")
                    .c_str(),
                r.ate.rmse, align_mode_name(r.align), r.matched);
  plot.title = title;
  write_trajectory_plot(args.plot, plot);
}

// The span coverage is measured over: the camera frames when every --gt is a
// dataset folder (its ground truth may start earlier and end later), the
// ground truth's own span otherwise.
std::vector<std::pair<TimestampNs, TimestampNs>> recording_spans(const std::vector<std::string>& gts) {
  std::vector<std::pair<TimestampNs, TimestampNs>> spans;
  for (const auto& g : gts) {
    std::error_code ec;
    if (!std::filesystem::is_directory(g, ec)) return {};
    if (is_kitti_sequence(g)) {
      const std::vector<TimestampNs> times = read_kitti_times(std::filesystem::path(g) / "times.txt");
      spans.emplace_back(times.front(), times.back());
      continue;
    }
    const EurocDataset dataset = read_euroc_dataset(g);
    if (dataset.cameras.empty() || dataset.cameras.front().frames.empty()) return {};
    const auto& frames = dataset.cameras.front().frames;
    spans.emplace_back(frames.front().t_ns, frames.back().t_ns);
  }
  return spans;
}

std::vector<Trajectory> read_parts(const std::vector<std::string>& paths) {
  std::vector<Trajectory> parts;
  for (const auto& p : paths) parts.push_back(read_any_ground_truth(p));
  return parts;
}

// Several trajectories (sessions in one world frame) as one, in time order.
Trajectory read_joined(const std::vector<std::string>& paths, std::vector<Trajectory> parts) {
  const std::string what = joined(paths) + " (only recordings made at different times can be joined)";
  return join_trajectories(parts, what.c_str());
}

// The ground truth of the camera (cam0) instead of the body: each --gt must be
// a dataset folder, whose cam0 calibration gives the camera in the body.
Trajectory read_camera_ground_truth(const std::vector<std::string>& gts) {
  std::vector<Trajectory> parts;
  for (const auto& g : gts) {
    std::error_code ec;
    ORBATLAS_CHECK(std::filesystem::is_directory(g, ec),
                   "--est-frame cam0 needs --gt dataset folders (their cam0 calibration), not " << g);
    const EurocDataset dataset = read_euroc_dataset(g);
    ORBATLAS_CHECK(!dataset.cameras.empty(), g << " has no cam0");
    parts.push_back(attached_frame(read_any_ground_truth(g), dataset.cameras.front().calibration.T_b_c));
  }
  const std::string what = joined(gts) + " (only recordings made at different times can be joined)";
  return join_trajectories(parts, what.c_str());
}

// --segments: lengths, or "auto"; without it, auto for KITTI ground truth only.
std::optional<std::vector<double>> segment_lengths(const EvalArgs& args) {
  if (args.segments.empty()) {
    for (const auto& g : args.gt) {
      std::error_code ec;
      const std::filesystem::path p(g);
      if ((std::filesystem::is_directory(p, ec) && is_kitti_sequence(p)) ||
          (std::filesystem::is_regular_file(p, ec) && looks_like_kitti_poses(p)))
        return std::vector<double>{};
    }
    return std::nullopt;
  }
  if (args.segments.size() == 1 && args.segments.front() == "auto") return std::vector<double>{};
  std::vector<double> lengths;
  for (const auto& text : args.segments) {
    char* end = nullptr;
    const double l = std::strtod(text.c_str(), &end);
    ORBATLAS_CHECK(end != text.c_str() && *end == '\0' && std::isfinite(l) && l > 0.0,
                   "--segments takes lengths in metres (> 0) or auto, not '" << text << "'");
    lengths.push_back(l);
  }
  return lengths;
}

void run_eval(const EvalArgs& args) {
  const Trajectory gt =
      args.est_frame == "cam0" ? read_camera_ground_truth(args.gt) : read_joined(args.gt, read_parts(args.gt));
  const std::vector<Trajectory> est_parts = read_parts(args.est);  // TUM usually; an ASL csv or dataset also works
  const Trajectory est = read_joined(args.est, est_parts);
  ORBATLAS_CHECK(!est.empty(), joined(args.est) << ": no poses");
  ORBATLAS_CHECK(!gt.empty(), joined(args.gt) << ": no poses");

  EvalOptions options;
  const auto mode = parse_align_mode(args.align);
  ORBATLAS_CHECK(mode.has_value(), "--align must be se3, sim3 or none, not '" << args.align << "'");
  options.align = *mode;
  options.association.max_gap_ns = s_to_ns(args.max_gap_s);
  options.spans = recording_spans(args.gt);
  options.segment_lengths_m = segment_lengths(args);
  const EvalResult result = evaluate_trajectory(est, gt, options);

  if (args.json) {
    nlohmann::ordered_json j = to_json(result);
    if (result.segments) j["kitti"] = to_json(*result.segments);
    std::cout << j.dump(2) << "\n";
  } else {
    print_human(args, result);
  }
  if (!args.plot.empty()) {
    write_plot(args, est_parts, gt, result);
    if (!args.json) std::cout << "  plot           " << args.plot << "\n";
  }
}

}  // namespace

void register_eval_command(CLI::App& app) {
  auto args = std::make_shared<EvalArgs>();
  CLI::App* cmd = app.add_subcommand("eval", "Evaluate an estimated trajectory against ground truth (ATE, RPE)");
  cmd->add_option("--gt", args->gt,
                  "Ground truth: TUM file, ASL state_groundtruth_estimate0 csv, KITTI poses file, or EuRoC or KITTI "
                  "dataset folder. Repeat it "
                  "(and --est) for several sessions in one world frame: they are joined in time order and aligned "
                  "with ONE transform")
      ->required();
  cmd->add_option(
         "--est", args->est,
         "Estimated trajectory: TUM (seconds or ORB-SLAM3 nanoseconds), or an ASL csv or dataset folder (repeatable)")
      ->required()
      ->check(CLI::ExistingPath);
  cmd->add_option("--align", args->align, "Alignment before ATE: se3 (rigid), sim3 (with scale) or none")
      ->check(CLI::IsMember({"se3", "sim3", "none"}))
      ->capture_default_str();
  cmd->add_option("--est-frame", args->est_frame,
                  "What the estimate's poses are of: body (the IMU frame, as stereo sessions report), or cam0 (the "
                  "camera, as monocular sessions report; the ground truth is moved to cam0 with each --gt dataset's "
                  "calibration)")
      ->check(CLI::IsMember({"body", "cam0"}))
      ->capture_default_str();
  cmd->add_option("--max-gap", args->max_gap_s, "Largest ground-truth gap [s] to interpolate across when associating")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--segments", args->segments,
                  "KITTI's relative errors (translation %, rotation deg/m) over path segments of these lengths in "
                  "metres (comma-separated), or auto: the benchmark's 100..800 m that fit the path, else tenths of "
                  "it. On by itself for KITTI ground truth")
      ->delimiter(',');
  cmd->add_flag("--json", args->json, "Print the result as one JSON object");
  cmd->add_option("--plot", args->plot, "Write a top-view (x-y) PNG of both trajectories");
  cmd->callback([args] { run_eval(*args); });
}

}  // namespace orbatlas::cli
