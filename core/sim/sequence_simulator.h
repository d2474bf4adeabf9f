#pragma once
// `orbatlas sim`: renders an EuRoC ASL dataset (stereo images, IMU, ground truth,
// sensor.yaml files) along a real EuRoC trajectory, at the real camera timestamps.
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

#include "core/sim/depth_sensor.h"
#include "core/sim/imu_synthesizer.h"
#include "core/sim/look.h"

namespace orbatlas::sim {

enum class ImuSource { kSynthetic, kReal };

struct SimulationOptions {
  std::string sequence = "MH_01";
  std::filesystem::path out_dir;
  double start_s = 0.0;      // skip this much of the sequence (from its first camera frame)
  double duration_s = -1.0;  // render this long; negative: to the end
  int every = 1;             // keep every n-th camera frame (sparse datasets, e.g. vocabulary training)
  std::uint64_t scene_seed = 1;
  // kReal: the real IMU recorded in that flight (MH_05, and MH_01's lossy
  // copy: timestamps rounded to microseconds, values to about 6 digits, gaps).
  ImuSource imu = ImuSource::kSynthetic;
  // What the synthetic IMU adds to the ideal measurement; empty: by the look
  // (clean: ideal_imu_errors(), real: realistic_imu_errors()). With the real
  // IMU only its time_offset_s is used (the real stamps shifted by it).
  std::optional<ImuErrorModel> imu_errors;
  double noise_sigma = 2.0;       // image noise, grey levels
  std::uint64_t sensor_seed = 0;  // IMU and image noise; 0: derived from the sequence name
  // Calibration of the rendered rig (ORB-SLAM3-style settings, stereo); empty:
  // the shipped config/euroc/stereo_inertial.yaml (the real EuRoC calibration).
  std::filesystem::path settings;
  Look look = Look::kClean;
  // The real look's settings; empty: real_look_for(sequence) (darker MH_04/MH_05).
  std::optional<RealLookOptions> real;
  // Also a depth camera registered to cam0, written in the TUM RGB-D layout
  // beside the ASL one (rgb.txt listing mav0/cam0's images, depth/, depth.txt,
  // groundtruth.txt of the body): what an rgbd config (config/euroc/rgbd.yaml) reads.
  std::optional<DepthSensorOptions> depth;
  // The images of an earlier rendering of the same sequence, look, range and
  // seeds, linked (or copied) instead of rendered again: a variant of its IMU.
  // Each image must be there (Error otherwise); not with `depth`.
  std::filesystem::path images_from;
  int threads = 0;  // 0: all cores
  bool show_progress = true;

  // Throws Error naming the first value out of range.
  void check() const;
};

struct SimulationReport {
  std::size_t frames = 0;             // stereo frames written
  std::size_t frames_outside_gt = 0;  // camera timestamps the ground truth does not cover (skipped)
  std::size_t imu_samples = 0;
  double world_build_s = 0.0;
  double render_s = 0.0;             // wall time of rendering and writing the images
  double render_ms_per_image = 0.0;  // CPU time per image (rendering only), averaged
  // Real look: renders averaged per image (motion blur), and the mean exposure.
  double subframes_per_image = 1.0;
  double mean_exposure_ms = 0.0;
  std::size_t depth_images = 0;  // with `depth`
};

// Throws Error on bad options (unknown sequence, --imu real for a sequence
// whose real IMU is not shipped (MH_01 and MH_05 are), an output folder that already holds a dataset, an empty time
// range).
SimulationReport simulate_sequence(const SimulationOptions& options);

}  // namespace orbatlas::sim
