// orbatlas sim: render an EuRoC-like dataset along a real trajectory.
#include <cstdio>

#include "client/commands.h"
#include "core/sim/sequence_simulator.h"

namespace orbatlas::cli {

void register_sim_command(CLI::App& app) {
  auto opts = std::make_shared<sim::SimulationOptions>();
  auto imu = std::make_shared<std::string>("synthetic");
  auto* cmd = app.add_subcommand("sim", "Render an EuRoC ASL dataset (stereo, IMU, ground truth) along a real EuRoC trajectory");
  cmd->add_option("--sequence", opts->sequence, "MH_01..MH_05 (one shared Machine Hall) or V1_01")->capture_default_str();
  cmd->add_option("--out", opts->out_dir, "Output folder (created; must not already hold a dataset)")->required();
  cmd->add_option("--start", opts->start_s, "Seconds to skip from the sequence's first frame")->capture_default_str();
  cmd->add_option("--duration", opts->duration_s, "Seconds to render (default: to the end)");
  cmd->add_option("--every", opts->every, "Keep every n-th camera frame")->capture_default_str();
  cmd->add_option("--scene-seed", opts->scene_seed, "Seed of the hall (same seed, same hall)")->capture_default_str();
  cmd->add_option("--imu", *imu, "IMU source: synthetic, or real (the real MH_05 IMU)")
      ->check(CLI::IsMember({"synthetic", "real"}))
      ->capture_default_str();
  cmd->add_option("--noise", opts->noise_sigma, "Image noise sigma in grey levels")->capture_default_str();
  cmd->add_option("--sensor-seed", opts->sensor_seed, "Seed of IMU and image noise (default: from the sequence name)");
  cmd->add_option("--config", opts->settings, "Rig calibration, ORB-SLAM3-style YAML (default: config/euroc/stereo_inertial.yaml)");
  cmd->add_option("--threads", opts->threads, "Render threads (default: all cores)");
  cmd->add_flag("!--no-progress", opts->show_progress, "Do not print progress");
  cmd->callback([opts, imu]() {
    opts->imu = *imu == "real" ? sim::ImuSource::kReal : sim::ImuSource::kSynthetic;
    const sim::SimulationReport r = sim::simulate_sequence(*opts);
    std::printf("wrote %zu stereo frames and %zu IMU samples to %s\n", r.frames, r.imu_samples, opts->out_dir.c_str());
    std::printf("world built in %.2f s; images rendered and written in %.1f s; render %.2f ms per image\n",
                r.world_build_s, r.render_s, r.render_ms_per_image);
    if (r.frames_outside_gt > 0) std::printf("skipped %zu camera timestamps outside the ground truth\n", r.frames_outside_gt);
  });
}

}  // namespace orbatlas::cli
