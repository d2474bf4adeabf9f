// `orbatlas localize`: tracks a stereo dataset against the maps of a stored atlas
// without changing them (no keyframe, no new map): relocalisation across every
// stored map to start and whenever tracking is lost, then tracking. The output
// holds the localised frames only, in the frame of the map recognised, with
// "# map <id>" lines (docs/cli.md).
#include <cstdio>
#include <map>
#include <memory>
#include <string>

#include "client/commands.h"
#include "core/common/error.h"
#include "core/io/tum_trajectory.h"
#include "core/slam/dataset_runner.h"

namespace orbatlas::cli {
namespace {

struct LocalizeArgs {
  DatasetRunOptions run;
  std::string config, dataset, out_trajectory, stats, vocabulary, atlas;
  double start_s = 0.0, duration_s = 0.0;
};

}  // namespace

void register_localize_command(CLI::App& app) {
  auto args = std::make_shared<LocalizeArgs>();
  auto* cmd = app.add_subcommand("localize", "Localise a stereo dataset against the maps of a stored atlas");
  cmd->add_option("--atlas", args->atlas, "Atlas database (orbatlas run --atlas)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--config", args->config, "ORB-SLAM3-style settings, e.g. config/euroc/stereo.yaml")->required();
  cmd->add_option("--dataset", args->dataset, "Folder holding mav0/ (cam0, cam1)")->required();
  cmd->add_option("--out-trajectory", args->out_trajectory,
                  "Localised poses (TUM, body frame, map frame; '# map <id>' lines)")
      ->required();
  cmd->add_option("--stats", args->stats, "Write run figures as JSON here");
  cmd->add_option("--vocabulary", args->vocabulary, "Vocabulary file (default: the shipped one)");
  cmd->add_option("--start", args->start_s, "Seconds of the sequence to skip")->capture_default_str();
  cmd->add_option("--duration", args->duration_s, "Seconds to run (default: to the end)");
  cmd->add_flag("!--no-progress", args->run.show_progress, "Do not print progress");
  cmd->callback([args]() {
    DatasetRunOptions options = args->run;
    options.settings = args->config;
    options.dataset = args->dataset;
    options.vocabulary = args->vocabulary;
    options.atlas = args->atlas;
    options.localize_only = true;
    options.start_s = args->start_s;
    if (args->duration_s > 0.0) options.duration_s = args->duration_s;

    const DatasetRunReport report = run_stereo_dataset(options);
    write_tum_trajectory(args->out_trajectory, report.trajectory, report.trajectory_maps);
    nlohmann::json j = report.to_json();
    std::map<MapId, std::size_t> per_map;
    for (const MapId m : report.trajectory_maps) ++per_map[m];
    j["localized"] = report.trajectory.size();
    j["localized_fraction"] =
        report.stats.frames > 0 ? static_cast<double>(report.trajectory.size()) / static_cast<double>(report.stats.frames)
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
