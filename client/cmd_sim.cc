// orbatlas sim: render an EuRoC-like dataset along a real trajectory.
#include <cstdio>

#include "client/commands.h"
#include "core/common/error.h"
#include "core/io/bag_dataset.h"
#include "core/io/euroc_reader.h"
#include "core/sim/sequence_simulator.h"

namespace orbatlas::cli {

void register_sim_command(CLI::App& app) {
  auto opts = std::make_shared<sim::SimulationOptions>();
  auto imu = std::make_shared<std::string>("synthetic");
  auto look = std::make_shared<std::string>("clean");
  auto calib_error = std::make_shared<double>(-1.0);
  auto illumination = std::make_shared<double>(-1.0);
  auto depth = std::make_shared<bool>(false);
  auto depth_options = std::make_shared<sim::DepthSensorOptions>();
  auto bag = std::make_shared<std::string>();
  auto imu_model = std::make_shared<std::string>();
  auto imu_offset_ms = std::make_shared<double>(0.0);
  auto imu_vibration = std::make_shared<double>(-1.0);
  auto imu_scale_error = std::make_shared<double>(-1.0);
  auto imu_extrinsic_error = std::make_shared<double>(-1.0);
  auto* cmd = app.add_subcommand(
      "sim", "Render an EuRoC ASL dataset (stereo, IMU, ground truth) along a real EuRoC trajectory");
  cmd->add_option("--sequence", opts->sequence, "MH_01..MH_05 (one shared Machine Hall) or V1_01")
      ->capture_default_str();
  cmd->add_option("--out", opts->out_dir, "Output folder (created; must not already hold a dataset)")->required();
  cmd->add_option("--start", opts->start_s, "Seconds to skip from the sequence's first frame")->capture_default_str();
  cmd->add_option("--duration", opts->duration_s, "Seconds to render (default: to the end)");
  cmd->add_option("--every", opts->every, "Keep every n-th camera frame")->capture_default_str();
  cmd->add_option("--scene-seed", opts->scene_seed, "Seed of the hall (same seed, same hall)")->capture_default_str();
  cmd->add_option("--imu", *imu,
                  "IMU source: synthetic, or real (the real IMU of the flight: MH_05, or MH_01's lossy copy)")
      ->check(CLI::IsMember({"synthetic", "real"}))
      ->capture_default_str();
  cmd->add_option("--imu-model", *imu_model,
                  "Synthetic IMU: ideal (the settings' noise, small biases) or realistic (the real EuRoC IMU's noise, "
                  "biases, vibration while the motors run, scale and mounting errors); default: ideal for the clean "
                  "look, realistic for the real look (docs/simulator.md)")
      ->check(CLI::IsMember({"ideal", "realistic"}));
  cmd->add_option(
         "--imu-time-offset-ms", *imu_offset_ms,
         "The IMU's clock is late by this against the cameras' (the sample stamped t measured time t - offset)")
      ->check(CLI::Range(-200.0, 200.0))
      ->capture_default_str();
  cmd->add_option("--imu-vibration", *imu_vibration,
                  "Scale of the real flights' vibration while the motors run (realistic model: 1; 0: none)")
      ->check(CLI::Range(0.0, 10.0));
  cmd->add_option("--imu-scale-error", *imu_scale_error,
                  "Sigma of each IMU axis' scale factor error (realistic model: 0.002)")
      ->check(CLI::Range(0.0, 0.05));
  cmd->add_option("--imu-extrinsic-error", *imu_extrinsic_error,
                  "Scale of the IMU mounting's error against the calibration (realistic model: 1 = 0.05 deg and 1 mm "
                  "per axis)")
      ->check(CLI::Range(0.0, 20.0));
  cmd->add_option("--look", *look,
                  "clean: dense procedural texture, constant exposure, Gaussian noise; real: sparse texture, "
                  "auto exposure, vignetting, motion blur, signal-dependent noise, darker MH_04/MH_05, "
                  "calibration error, IMU vibration (docs/simulator.md)")
      ->check(CLI::IsMember({"clean", "real"}))
      ->capture_default_str();
  cmd->add_option("--calib-error", *calib_error,
                  "Real look: scale of the difference between the rendering and the written calibration (default 0: "
                  "none; 1: a good real calibration's error)")
      ->check(CLI::Range(0.0, 20.0));
  cmd->add_option("--illumination", *illumination,
                  "Real look: scene illumination relative to a well-lit hall (default 1, MH_04/MH_05 0.12)")
      ->check(CLI::Range(0.01, 10.0));
  cmd->add_option("--noise", opts->noise_sigma, "Clean look: image noise sigma in grey levels")->capture_default_str();
  cmd->add_option("--sensor-seed", opts->sensor_seed, "Seed of IMU and image noise (default: from the sequence name)");
  cmd->add_option("--config", opts->settings,
                  "Rig calibration, ORB-SLAM3-style YAML (default: config/euroc/stereo_inertial.yaml)");
  cmd->add_flag("--depth", *depth,
                "Also a depth camera registered to cam0, in the TUM RGB-D layout beside the ASL one (rgb.txt, "
                "depth.txt, depth/, groundtruth.txt; read with config/euroc/rgbd.yaml): noise growing with the "
                "square of the depth, holes at depth edges and out of range (docs/simulator.md)");
  cmd->add_option("--depth-range", depth_options->max_range_m, "With --depth: farthest depth measured [m]")
      ->check(CLI::Range(0.5, 13.0))
      ->capture_default_str();
  cmd->add_option("--depth-noise", depth_options->noise_per_m2,
                  "With --depth: depth noise sigma per squared metre (0: exact)")
      ->check(CLI::Range(0.0, 0.1))
      ->capture_default_str();
  cmd->add_option("--bag", *bag,
                  "Also write the recording as a ROS 1 bag here (/cam0/image_raw, /cam1/image_raw: sensor_msgs/Image "
                  "mono8; /imu0: sensor_msgs/Imu), as EuRoC distributes its sequences");
  cmd->add_option("--images-from", opts->images_from,
                  "Link the images of an earlier rendering of the same sequence, look and range instead of rendering "
                  "them (an IMU variant: --imu, --imu-model, --imu-time-offset-ms ...)");
  cmd->add_option("--threads", opts->threads, "Render threads (default: all cores)");
  cmd->add_flag("!--no-progress", opts->show_progress, "Do not print progress");
  cmd->callback([opts, imu, look, calib_error, illumination, depth, depth_options, bag, imu_model, imu_offset_ms,
                 imu_vibration, imu_scale_error, imu_extrinsic_error]() {
    if (*depth) opts->depth = *depth_options;
    opts->imu = *imu == "real" ? sim::ImuSource::kReal : sim::ImuSource::kSynthetic;
    opts->look = sim::parse_look(*look);
    const bool realistic = imu_model->empty() ? opts->look == sim::Look::kReal : *imu_model == "realistic";
    sim::ImuErrorModel errors = realistic ? sim::realistic_imu_errors() : sim::ideal_imu_errors();
    errors.time_offset_s = *imu_offset_ms * 1e-3;
    if (*imu_vibration >= 0.0) errors.vibration = *imu_vibration;
    if (*imu_scale_error >= 0.0) errors.scale_error = *imu_scale_error;
    if (*imu_extrinsic_error >= 0.0) {
      const sim::ImuErrorModel r = sim::realistic_imu_errors();
      errors.extrinsic_rotation_deg = *imu_extrinsic_error * r.extrinsic_rotation_deg;
      errors.extrinsic_translation_m = *imu_extrinsic_error * r.extrinsic_translation_m;
    }
    opts->imu_errors = errors;
    if ((*calib_error >= 0.0 || *illumination > 0.0) && opts->look != sim::Look::kReal)
      throw Error("--calib-error and --illumination belong to --look real");
    if (opts->look == sim::Look::kReal) {
      sim::RealLookOptions real = sim::real_look_for(opts->sequence);
      if (*calib_error >= 0.0) real.calibration_error = *calib_error;
      if (*illumination > 0.0) real.camera.illumination = *illumination;
      opts->real = real;
    }
    const sim::SimulationReport r = sim::simulate_sequence(*opts);
    std::printf("wrote %zu stereo frames and %zu IMU samples to %s\n", r.frames, r.imu_samples, opts->out_dir.c_str());
    std::printf("world built in %.2f s; images rendered and written in %.1f s; render %.2f ms per image\n",
                r.world_build_s, r.render_s, r.render_ms_per_image);
    if (opts->look == sim::Look::kReal)
      std::printf("real look: %.2f renders per image (motion blur), mean exposure %.1f ms\n", r.subframes_per_image,
                  r.mean_exposure_ms);
    if (r.depth_images > 0)
      std::printf("and %zu depth images (TUM RGB-D layout: rgb.txt, depth.txt)\n", r.depth_images);
    if (r.frames_outside_gt > 0)
      std::printf("skipped %zu camera timestamps outside the ground truth\n", r.frames_outside_gt);
    if (!bag->empty()) {
      write_bag(read_euroc_dataset(opts->out_dir), BagTopics{}, *bag);
      std::printf("and the bag %s (the same images and IMU)\n", bag->c_str());
    }
  });
}

}  // namespace orbatlas::cli
