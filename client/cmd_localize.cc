// `orbatlas localize`: tracks a stereo dataset (EuRoC ASL, KITTI odometry) against the maps of a stored atlas
// without changing them (no keyframe, no new map): relocalisation across every
// stored map to start and whenever tracking is lost, then tracking. The output
// holds the localised frames only, in the frame of the map recognised, with
// "# map <id>" lines (docs/cli.md). With --server, one image (or stereo pair)
// is sent to a running map server instead (POST /v1/localize) and its pose printed.
#include <chrono>
#include <cstdio>
#include <map>
#include <memory>
#include <string>

#include <opencv2/imgcodecs.hpp>

#include "client/api/server_client.h"
#include "client/commands.h"
#include "core/common/text_file.h"
#include "core/io/euroc_reader.h"
#include "core/io/kitti_odometry.h"
#include "wire/pose_json.h"
#include "client/bag_options.h"
#include "core/slam/slam_stats.h"
#include "wire/stats_json.h"
#include "core/common/error.h"
#include "core/io/euroc_trajectory.h"
#include "core/io/tum_trajectory.h"
#include "core/pipeline/dataset_runner.h"
#include "wire/run_report_json.h"

namespace orbatlas::cli {
namespace {

struct LocalizeArgs {
  DatasetRunOptions run;
  std::string config, dataset, out_trajectory, stats, vocabulary, atlas, format = "tum";
  double start_s = 0.0, duration_s = 0.0;
  // --server mode
  std::string server, token, ca, image, image_right;
  std::optional<std::uint64_t> map;
  std::size_t every = 10;
  BagArgs bag;
};

// --server with --dataset: every N-th frame's left image (a single image, as a
// phone would send) is localised; prints how many were recognised and the
// request latency, and writes the poses (TUM, '# map' lines) when asked.
void localize_dataset_on_server(const LocalizeArgs& args) {
  std::vector<ImageFrame> images;
  SettingsChoice settings;
  if (is_kitti_sequence(args.dataset)) {
    const KittiSequence kitti = read_kitti_sequence(args.dataset);
    for (const DatasetFrame& f : kitti.frames) images.push_back({f.t_ns, f.left});
    // Its own settings (calib.txt), unless --config names others.
    settings = args.config.empty() ? SettingsChoice{"", kitti_settings_yaml(kitti)} : choose_settings(args.config);
  } else {
    ORBATLAS_CHECK(!args.config.empty(), "localize: --config is needed for " << args.dataset);
    EurocReadOptions read_options;
    read_options.require_cam1 = false;
    const EurocDataset dataset = read_euroc_dataset(args.dataset, read_options);
    ORBATLAS_CHECK(!dataset.cameras.empty() && !dataset.cameras[0].frames.empty(),
                   args.dataset << " has no cam0 images");
    images = dataset.cameras[0].frames;
    settings = choose_settings(args.config);  // a local file is read once
  }
  ServerClient client(args.server, args.token, args.ca);
  Trajectory poses;
  std::vector<std::uint64_t> maps;
  std::vector<double> ms, server_ms;
  std::size_t asked = 0;
  for (std::size_t i = 0; i < images.size(); i += std::max<std::size_t>(1, args.every)) {
    const cv::Mat left = cv::imread(images[i].path.string(), cv::IMREAD_GRAYSCALE);
    if (left.empty()) continue;
    ++asked;
    const auto start = std::chrono::steady_clock::now();
    const auto reply =
        client.localize(settings.config, left, cv::Mat(), args.map, ImageEncoding::kPng, settings.settings_yaml);
    ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
    server_ms.push_back(reply.at("ms").get<double>());
    if (!reply.at("recognised").get<bool>()) continue;
    poses.push_back({images[i].t_ns, pose_from_json(reply.at("T_w_b"))});
    maps.push_back(reply.at("map").get<std::uint64_t>());
  }
  ORBATLAS_CHECK(asked > 0, "no readable image in " << args.dataset);
  const Percentiles p = percentiles(ms), ps = percentiles(server_ms);
  std::printf(
      "recognised %zu of %zu images (%.1f%%); POST /v1/localize p50 %.1f / p95 %.1f ms (in the server p50 %.1f / p95 "
      "%.1f ms)\n",
      poses.size(), asked, 100.0 * static_cast<double>(poses.size()) / static_cast<double>(asked), p.p50, p.p95, ps.p50,
      ps.p95);
  if (!args.out_trajectory.empty())
    write_trajectory(args.out_trajectory, poses, maps, parse_trajectory_format(args.format));
  if (!args.stats.empty())
    write_stats_file(args.stats, {{"asked", asked},
                                  {"recognised", poses.size()},
                                  {"request_ms", to_json_summary(ms)},
                                  {"server_ms", to_json_summary(server_ms)}});
}

void localize_on_server(const LocalizeArgs& args) {
  ORBATLAS_CHECK(!args.image.empty(), "localize --server needs --image LEFT.png (and --image-right for a stereo pair)");
  ORBATLAS_CHECK(!args.config.empty(), "localize --server --image needs --config (a config name or a settings file)");
  const cv::Mat left = cv::imread(args.image, cv::IMREAD_GRAYSCALE);
  ORBATLAS_CHECK(!left.empty(), "cannot read image " << args.image);
  cv::Mat right;
  if (!args.image_right.empty()) {
    right = cv::imread(args.image_right, cv::IMREAD_GRAYSCALE);
    ORBATLAS_CHECK(!right.empty(), "cannot read image " << args.image_right);
  }
  ServerClient client(args.server, args.token, args.ca);
  // A local YAML file travels inline; anything else is a config name the server knows.
  const auto reply = client.localize(args.config, left, right, args.map, ImageEncoding::kPng);
  if (!reply.at("recognised").get<bool>()) {
    std::printf("not recognised: %s (%zu candidates, %.1f ms)\n", reply.value("reason", "").c_str(),
                reply.value("candidates", std::size_t{0}), reply.value("ms", 0.0));
    throw Error("the place was not recognised");
  }
  const auto& t = reply.at("T_w_b").at("t");
  const auto& q = reply.at("T_w_b").at("q");
  std::printf("map %llu: T_w_b t = [%.4f %.4f %.4f] q = [%.5f %.5f %.5f %.5f] (%d inliers, %.1f ms)\n",
              static_cast<unsigned long long>(reply.at("map").get<std::uint64_t>()), t[0].get<double>(),
              t[1].get<double>(), t[2].get<double>(), q[0].get<double>(), q[1].get<double>(), q[2].get<double>(),
              q[3].get<double>(), reply.at("inliers").get<int>(), reply.at("ms").get<double>());
}

}  // namespace

void register_localize_command(CLI::App& app) {
  auto args = std::make_shared<LocalizeArgs>();
  auto* cmd = app.add_subcommand("localize", "Localise a stereo dataset against the maps of a stored atlas");
  cmd->add_option("--atlas", args->atlas, "Atlas database (orbatlas run --atlas)")->check(CLI::ExistingFile);
  cmd->add_option("--config", args->config,
                  "ORB-SLAM3-style settings, e.g. config/euroc/stereo.yaml (with --server: also a config name, "
                  "e.g. euroc/stereo); a KITTI sequence's come from its calib.txt without it");
  cmd->add_option("--dataset", args->dataset,
                  "Folder holding mav0/ (cam0, cam1), or a KITTI odometry sequence (image_0/, image_1/, times.txt, "
                  "calib.txt)");
  add_bag_options(cmd, args->bag, false);
  cmd->add_option("--out-trajectory", args->out_trajectory,
                  "Localised poses (body frame, map frame; '# map <id>' lines; --format)");
  cmd->add_option("--format", args->format,
                  "Trajectory file format: tum (t tx ty tz qx qy qz qw, seconds) or euroc (the csv of EuRoC's ground "
                  "truth: ns,px,py,pz,qw,qx,qy,qz; what evo_traj euroc reads)")
      ->capture_default_str()
      ->check(CLI::IsMember({"tum", "euroc"}));
  cmd->add_option("--server", args->server, "Ask a running map server instead, e.g. http://127.0.0.1:8080");
  cmd->add_option("--token", args->token, "Bearer token of the server")->envname("ORBATLAS_TOKEN");
  cmd->add_option("--ca", args->ca, "With an https:// server: the certificate authority (PEM) to check it against")
      ->envname("ORBATLAS_CA");
  cmd->add_option("--image", args->image, "With --server: the (left) image to localise");
  cmd->add_option("--image-right", args->image_right, "With --server: the right image of a stereo pair");
  cmd->add_option("--map", args->map, "With --server: only this map");
  cmd->add_option("--stats", args->stats, "Write run figures as JSON here");
  cmd->add_option("--vocabulary", args->vocabulary, "Vocabulary file (default: the shipped one)");
  cmd->add_option("--start", args->start_s, "Seconds of the sequence to skip")->capture_default_str();
  cmd->add_option("--duration", args->duration_s, "Seconds to run (default: to the end)");
  cmd->add_flag("!--no-progress", args->run.show_progress, "Do not print progress");
  cmd->add_option("--every", args->every, "With --server and --dataset: localise every N-th frame")
      ->capture_default_str();
  cmd->callback([args, cmd]() {
    std::unique_ptr<UnpackedBags> bag;
    if (!args->bag.bags.empty()) args->dataset = dataset_or_bag(args->dataset, args->bag, bag, args->run.show_progress);
    if (!args->server.empty() && !args->dataset.empty()) return localize_dataset_on_server(*args);
    if (!args->server.empty()) return localize_on_server(*args);
    ORBATLAS_CHECK(!args->atlas.empty() && !args->dataset.empty() && !args->out_trajectory.empty(),
                   "localize needs --atlas, --dataset (or --bag) and --out-trajectory (or --server and --image)");
    log_effective_options(*cmd);
    DatasetRunOptions options = args->run;
    options.settings = args->config;
    options.dataset = args->dataset;
    options.vocabulary = args->vocabulary;
    options.atlas = args->atlas;
    options.localize_only = true;
    options.start_s = args->start_s;
    if (args->duration_s > 0.0) options.duration_s = args->duration_s;

    const DatasetRunReport report = run_dataset(options);
    write_trajectory(args->out_trajectory, report.trajectory, report.trajectory_maps,
                     parse_trajectory_format(args->format));
    nlohmann::json j = to_json(report);
    std::map<MapId, std::size_t> per_map;
    for (const MapId m : report.trajectory_maps) ++per_map[m];
    j["localized"] = report.trajectory.size();
    j["localized_fraction"] = report.stats.frames > 0 ? static_cast<double>(report.trajectory.size()) /
                                                            static_cast<double>(report.stats.frames)
                                                      : 0.0;
    if (!args->stats.empty()) write_stats_file(args->stats, j);
    print_run_summary(report);
    std::printf("localised %zu of %zu frames (%.1f%%)", report.trajectory.size(), report.stats.frames,
                100.0 * j["localized_fraction"].get<double>());
    for (const auto& [map, n] : per_map) std::printf("; map %llu: %zu", static_cast<unsigned long long>(map), n);
    std::printf("\ntrajectory: %zu poses -> %s\n", report.trajectory.size(), args->out_trajectory.c_str());
  });
}

}  // namespace orbatlas::cli
