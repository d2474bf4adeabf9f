// `orbatlas run`: stereo SLAM over an EuRoC ASL dataset; writes the trajectory
// (TUM, body frame) and optionally a stats JSON.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "client/effective_options.h"
#include "client/bag_options.h"
#include "client/commands.h"
#include "core/common/error.h"
#include "core/common/log.h"
#include "core/io/euroc_trajectory.h"
#include "core/io/tum_trajectory.h"
#include "core/pipeline/dataset_runner.h"
#include "wire/run_report_json.h"

namespace orbatlas::cli {
namespace {

struct RunArgs {
  DatasetRunOptions run;
  std::string config, stats, vocabulary, culling = "incremental", mode = "map", sensor;
  std::vector<std::string> datasets, out_trajectories, out_live_trajectories;
  std::string format = "tum";
  double start_s = 0.0, duration_s = 0.0;
  bool compare_culling = false;
  std::string black_out;  // FROM:TO seconds
  BagArgs bag;
};

std::pair<double, double> parse_black_out(const std::string& text) {
  const auto colon = text.find(':');
  try {
    if (colon != std::string::npos) {
      std::size_t end_from = 0, end_to = 0;
      const double from = std::stod(text.substr(0, colon), &end_from);
      const double to = std::stod(text.substr(colon + 1), &end_to);
      if (end_from == colon && end_to == text.size() - colon - 1) return {from, to};
    }
  } catch (const std::exception&) {
  }
  throw Error("--black-out takes FROM:TO in seconds (e.g. 40:41), not '" + text + "'");
}

}  // namespace

void write_stats_file(const std::string& path, const nlohmann::json& stats) {
  std::ofstream out(path);
  ORBATLAS_CHECK(out, "cannot write " << path);
  out << stats.dump(2) << "\n";
  ORBATLAS_CHECK(out.good(), "error writing " << path);
}

void log_effective_options(const CLI::App& command) {
  log_info("orbatlas " + command.get_name() + ": options in effect:\n" + effective_options_text(command));
}

void print_run_summary(const DatasetRunReport& r) {
  const auto t = percentiles(r.stats.tracking_ms);
  const auto m = percentiles(r.stats.mapping.keyframe_ms);
  std::printf("frames %zu, tracked %zu, lost %zu, skipped %zu; maps %zu, keyframes %zu, map points %zu\n",
              r.stats.frames, r.stats.tracked, r.stats.lost, r.skipped_frames, r.stats.maps, r.stats.keyframes,
              r.stats.mappoints);
  std::printf("tracking ms p50 %.1f p95 %.1f max %.1f; local mapping ms/keyframe p50 %.1f p95 %.1f\n", t.p50, t.p95,
              t.max, m.p50, m.p95);
  std::printf("peak RSS %.0f MB; wall %.1f s", r.peak_rss_mb, r.wall_s);
  if (r.late_frames > 0 || r.stats.frames > 0) std::printf("; late frames %zu", r.late_frames);
  std::printf("\n");
  if (r.stats.loop_closing) {
    const auto pr = percentiles(r.stats.loop.place_recognition_ms);
    std::printf("loops %zu", r.stats.loop.loops.size());
    if (!r.stats.loop_error_m.empty()) {
      std::size_t false_loops = 0;
      for (std::size_t i = 0; i < r.stats.loop_error_m.size(); ++i)
        if (r.stats.loop_error_m[i] > kFalseLoopM || r.stats.loop_error_deg[i] > kFalseLoopDeg) ++false_loops;
      std::printf(" (false by the ground truth: %zu)", false_loops);
    }
    std::printf("; place recognition ms/keyframe p50 %.1f p95 %.1f", pr.p50, pr.p95);
    for (const auto& loop : r.stats.loop.loops) std::printf("; correction %.0f ms", loop.correction.total_ms);
    for (const auto& g : r.stats.loop.global_adjustments)
      std::printf("; global BA (%s) %zu keyframes %.2f s%s", to_string(g.cause), g.keyframes, g.seconds,
                  g.interrupted ? " (interrupted)" : "");
    std::printf("\n");
    if (r.stats.maps_started > 1 || !r.stats.loop.merges.empty()) {
      std::printf("maps started %zu, merged live %zu", r.stats.maps_started, r.stats.loop.merges.size());
      for (const auto& merged : r.stats.loop.merges)
        std::printf("; map %llu into %llu at %.2f s (%d matches, %zu keyframes moved, %.0f ms)",
                    static_cast<unsigned long long>(merged.merge.source),
                    static_cast<unsigned long long>(merged.merge.target),
                    static_cast<double>(merged.current_t_ns) * 1e-9, merged.matches, merged.merge.keyframes_moved,
                    merged.merge.ms);
      std::printf("\n");
    }
  }
  if (r.stats.final_ba_keyframes > 0)
    std::printf("final global BA (--final-ba): %zu keyframes, %.2f s\n", r.stats.final_ba_keyframes,
                r.stats.final_ba_s);
  if (r.session) {
    std::printf("atlas: %zu maps / %zu keyframes loaded in %.2f s; stored as session %llu", r.loaded_maps,
                r.loaded_keyframes, r.atlas_load_s, static_cast<unsigned long long>(*r.session));
    if (r.checkpoints) {
      const auto c = r.checkpoints->wall_ms.percentiles();
      std::printf(" by %llu checkpoints (%llu commits, %llu failures; ms p50 %.1f max %.1f, off the tracking thread)",
                  static_cast<unsigned long long>(r.checkpoints->checkpoints),
                  static_cast<unsigned long long>(r.checkpoints->commits),
                  static_cast<unsigned long long>(r.checkpoints->failures), c.p50, c.max);
    }
    std::printf("\n");
  }
  if (r.ate_rmse_m)
    std::printf("ATE RMSE (%s, against the dataset's ground truth) %.4f m\n",
                r.ate_sim3 ? "Sim3, of the camera" : "SE3", *r.ate_rmse_m);
  if (r.live_ate_rmse_m) {
    std::printf("live poses (as tracking returned them, before any correction): %zu, ATE RMSE %.4f m",
                r.live_trajectory.size(), *r.live_ate_rmse_m);
    if (!r.live_jumps_m.empty())
      std::printf("; %zu jumps at corrections, max %.3f m", r.live_jumps_m.size(),
                  *std::max_element(r.live_jumps_m.begin(), r.live_jumps_m.end()));
    std::printf("\n");
  }
  if (r.black_out) {
    const auto& b = *r.black_out;
    std::printf("black-out: %zu frames, %zu carried by the IMU", b.frames, b.by_imu);
    if (b.error_at_end_m) std::printf(", %.3f m off at its end", *b.error_at_end_m);
    if (b.frames_to_visual) {
      std::printf(", tracked visually again %zu frames after it\n", *b.frames_to_visual);
    } else {
      std::printf(", not tracked visually again\n");
    }
  }
}

void register_run_command(CLI::App& app) {
  auto args = std::make_shared<RunArgs>();
  auto* cmd = app.add_subcommand(
      "run",
      "SLAM over an EuRoC ASL dataset (stereo, stereo-inertial), a KITTI odometry sequence (stereo) or a TUM RGB-D "
      "one (rgbd), real or simulated");
  cmd->add_option("--config", args->config,
                  "ORB-SLAM3-style settings, e.g. config/euroc/stereo.yaml (a KITTI sequence's come from its "
                  "calib.txt without it)");
  cmd->add_option("--dataset", args->datasets,
                  "Folder holding mav0/ (cam0, cam1), a KITTI odometry sequence (image_0/, image_1/, times.txt, "
                  "calib.txt), or rgb.txt and depth.txt for an rgbd config; repeat it to run "
                  "several recordings at once into one atlas "
                  "(one session each, mapping shared maps together)");
  add_bag_options(cmd, args->bag, true);
  cmd->add_option("--out-live-trajectory", args->out_live_trajectories,
                  "The poses tracking returned, frame by frame, before any correction (what a device would have "
                  "steered by; --format, '# map' lines); one per --dataset and --bag, as --out-trajectory");
  cmd->add_option("--out-trajectory", args->out_trajectories,
                  "Trajectory to write (body frame; --format); one per --dataset, then one per --bag, in that order")
      ->required();
  cmd->add_option("--format", args->format,
                  "Trajectory file format: tum (t tx ty tz qx qy qz qw, seconds) or euroc (the csv of EuRoC's ground "
                  "truth: ns,px,py,pz,qw,qx,qy,qz; what evo_traj euroc reads)")
      ->capture_default_str()
      ->check(CLI::IsMember({"tum", "euroc"}));
  cmd->add_option("--stats", args->stats,
                  "Write run figures as JSON here (several recordings: {\"runs\": [one object each]})");
  cmd->add_flag("--realtime", args->run.realtime, "Feed frames at the sensor rate and count late frames");
  cmd->add_option("--vocabulary", args->vocabulary, "Vocabulary file (default: the shipped one)");
  cmd->add_option("--start", args->start_s, "Seconds of the sequence to skip")->capture_default_str();
  cmd->add_option("--duration", args->duration_s, "Seconds to run (default: to the end)");
  cmd->add_option("--culling", args->culling, "Keyframe redundancy counting: scan or incremental")
      ->check(CLI::IsMember({"scan", "incremental"}))
      ->capture_default_str();
  cmd->add_flag("--compare-culling", args->compare_culling,
                "Also run the other redundancy scheme at every culling decision and count disagreements");
  cmd->add_flag("--synchronous", args->run.slam.synchronous_mapping,
                "Wait for local mapping after each keyframe (deterministic, slower)");
  cmd->add_option("--atlas", args->run.atlas,
                  "Atlas database: load its maps first, store this run as a new session (created if missing)");
  cmd->add_option("--checkpoint-keyframes", args->run.checkpoints.every_keyframes,
                  "With --atlas: checkpoint every N keyframes")
      ->capture_default_str();
  cmd->add_option("--checkpoint-seconds", args->run.checkpoints.every_seconds,
                  "With --atlas: and at least every T seconds")
      ->capture_default_str();
  cmd->add_flag("!--no-loop-closing", args->run.slam.loop_closing,
                "No place recognition, loop correction or global bundle adjustment");
  cmd->add_flag("!--no-progress", args->run.show_progress, "Do not print progress");
  cmd->add_option("--mode", args->mode,
                  "map (track, add keyframes, close loops) or localize (with --atlas: track in the stored maps and "
                  "change nothing, as `orbatlas localize` does)")
      ->check(CLI::IsMember({"map", "localize"}))
      ->capture_default_str();
  cmd->add_option("--sensor", args->sensor,
                  "mono or mono_inertial: the left camera of a stereo config alone (rectified as the rig's stereo "
                  "maps are, so its map can merge into them and take their metric scale)")
      ->check(CLI::IsMember({"mono", "mono_inertial"}));
  cmd->add_flag("--final-ba", args->run.slam.final_global_ba,
                "After the last frame, one global bundle adjustment over the session's maps (offline refinement; "
                "several recordings: over their maps once all ended)");
  cmd->add_option("--black-out", args->black_out,
                  "FROM:TO: every image black from FROM to TO seconds after the first frame (what the IMU carries a "
                  "stereo-inertial session through; the stats JSON reports black_out)");
  cmd->callback([args, cmd]() {
    log_effective_options(*cmd);
    DatasetRunOptions options = args->run;
    options.settings = args->config;
    options.vocabulary = args->vocabulary;
    options.start_s = args->start_s;
    if (args->duration_s > 0.0) options.duration_s = args->duration_s;
    options.slam.mapper.culling.scheme = args->culling == "scan" ? CullingScheme::kScan : CullingScheme::kIncremental;
    options.slam.mapper.culling.compare_schemes = args->compare_culling;
    if (!args->sensor.empty()) options.sensor = parse_sensor_type(args->sensor);
    options.localize_only = args->mode == "localize";  // DatasetRunOptions::check: needs --atlas
    if (!args->black_out.empty()) options.black_out_s = parse_black_out(args->black_out);

    const std::size_t recordings = args->datasets.size() + args->bag.bags.size();
    if (recordings == 0) throw Error("give a recording: --dataset FOLDER or --bag FILE");
    if (!args->out_live_trajectories.empty() && args->out_live_trajectories.size() != recordings)
      throw Error("give one --out-live-trajectory per --dataset and --bag, or none");
    if (args->out_trajectories.size() != recordings)
      throw Error("give one --out-trajectory per --dataset and --bag (" + std::to_string(recordings) + " recordings, " +
                  std::to_string(args->out_trajectories.size()) + " trajectories)");
    const UnpackedBags bags(args->bag, options.show_progress);
    std::vector<std::filesystem::path> datasets(args->datasets.begin(), args->datasets.end());
    std::vector<std::string> names = args->datasets;
    for (const auto& dir : bags.datasets()) datasets.push_back(dir);
    names.insert(names.end(), args->bag.bags.begin(), args->bag.bags.end());
    options.dataset = datasets.front();
    const std::vector<DatasetRunReport> reports = run_datasets(options, datasets);
    nlohmann::json runs = nlohmann::json::array();
    std::string failed;
    for (std::size_t i = 0; i < reports.size(); ++i) {
      const DatasetRunReport& report = reports[i];
      write_trajectory(args->out_trajectories[i], report.trajectory, {}, parse_trajectory_format(args->format));
      if (i < args->out_live_trajectories.size())
        write_trajectory(args->out_live_trajectories[i], report.live_trajectory, report.live_maps,
                         parse_trajectory_format(args->format));
      runs.push_back(to_json(report));
      if (reports.size() > 1) std::printf("== %s\n", names[i].c_str());
      print_run_summary(report);
      if (reports.size() == 1 && report.stats.maps > report.loaded_maps + 1)
        std::printf("note: tracking was lost and %zu maps were made; the trajectory mixes their frames\n",
                    report.stats.maps - report.loaded_maps);
      std::printf("trajectory: %zu poses -> %s\n", report.trajectory.size(), args->out_trajectories[i].c_str());
      if (!report.failed.empty() && failed.empty())
        failed = "the session of " + names[i] + " failed after " + std::to_string(report.stats.frames) + " frames (" +
                 report.failed + ")";
    }
    if (reports.size() > 1) {
      std::set<MapId> maps;
      for (const auto& report : reports) maps.insert(report.trajectory_maps.begin(), report.trajectory_maps.end());
      std::printf("%zu recordings at once: their trajectories end in %zu map(s)\n", reports.size(), maps.size());
    }
    if (!args->stats.empty())
      write_stats_file(args->stats, reports.size() == 1 ? runs[0] : nlohmann::json{{"runs", runs}});
    if (!failed.empty()) throw Error(failed + "; the trajectories and figures until then were written");
  });
}

}  // namespace orbatlas::cli
