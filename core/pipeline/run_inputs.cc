#include "core/pipeline/run_inputs.h"

#include "core/common/error.h"
#include "core/common/log.h"
#include "core/io/kitti_odometry.h"
#include "core/io/tum_rgbd.h"
#include "core/io/tum_trajectory.h"
#include "core/persistence/map_rigs.h"

namespace orbatlas {
namespace {

// An RGB-D recording in the TUM layout: each colour image with its depth image
// as the frame's two images, and the ground truth when there is one.
RunInputs read_rgbd_inputs(const DatasetRunOptions& options, SlamSettings settings) {
  RunInputs in;
  in.settings = std::move(settings);
  const TumRgbdDataset d = read_tum_rgbd(options.dataset);
  if (d.unpaired > 0)
    log_warn(options.dataset.string() + ": " + std::to_string(d.unpaired) +
             " colour images without a depth image within 0.02 s (skipped)");
  in.frames = rgbd_image_pairs(d);
  ORBATLAS_CHECK(!in.frames.empty(), options.dataset << " holds no colour image with a depth image");
  in.dataset.ground_truth = ground_truth_states(d);
  keep_time_window(in.frames, options.start_s, options.duration_s, options.dataset);
  return in;
}

// A KITTI odometry sequence: its stereo pairs, its settings from calib.txt
// unless a settings file is given, its poses as the ground truth (camera 0 is
// the body). --sensor mono takes the left images alone.
RunInputs read_kitti_inputs(const DatasetRunOptions& options) {
  const KittiSequence sequence = read_kitti_sequence(options.dataset);
  RunInputs in;
  if (options.settings.empty()) {
    in.settings = read_settings_text(kitti_settings_yaml(sequence), (options.dataset / "calib.txt").string());
    log_info("run: " + options.dataset.string() +
             " is a KITTI odometry sequence; its settings come from calib.txt "
             "(rectified stereo, ORB-SLAM3's KITTI features; docs/kitti.md)");
  } else {
    in.settings = read_settings(options.settings, SensorType::kStereo);
  }
  ORBATLAS_CHECK(in.settings.sensor == SensorType::kStereo, "run: a KITTI sequence is stereo without an IMU; "
                                                                << options.settings << " is a "
                                                                << sensor_type_name(in.settings.sensor) << " one");
  if (options.sensor) {
    ORBATLAS_CHECK(*options.sensor == SensorType::kMonocular,
                   "run: a KITTI sequence has no IMU: --sensor can be mono (its left camera), not "
                       << sensor_type_name(*options.sensor));
    in.settings.sensor = SensorType::kMonocular;
  }
  for (const DatasetFrame& f : sequence.frames)
    in.frames.push_back(options.sensor ? DatasetFrame{f.t_ns, f.left, {}} : f);
  in.dataset.ground_truth = ground_truth_states(sequence.ground_truth);
  keep_time_window(in.frames, options.start_s, options.duration_s, options.dataset);
  return in;
}

}  // namespace

RunInputs read_run_inputs(const DatasetRunOptions& options) {
  if (is_kitti_sequence(options.dataset)) return read_kitti_inputs(options);
  ORBATLAS_CHECK(!options.settings.empty(), "run: --config is needed for "
                                                << options.dataset
                                                << " (only a KITTI sequence's settings come from its calib.txt)");
  SlamSettings settings = read_settings(options.settings, SensorType::kStereo);
  if (options.sensor && *options.sensor != settings.sensor) {
    const bool inertial = *options.sensor == SensorType::kMonocularInertial;
    ORBATLAS_CHECK(settings.is_stereo() && is_single_camera(*options.sensor),
                   "run: --sensor " << sensor_type_name(*options.sensor)
                                    << " takes the left camera of a stereo config; " << options.settings << " is a "
                                    << sensor_type_name(settings.sensor) << " one");
    ORBATLAS_CHECK(!inertial || settings.imu,
                   "run: --sensor mono_inertial needs the IMU.* keys in " << options.settings);
    settings.sensor = *options.sensor;
    if (!inertial) settings.imu.reset();
  }
  if (settings.is_rgbd()) return read_rgbd_inputs(options, std::move(settings));
  RunInputs in;
  in.settings = std::move(settings);
  const bool single_camera =
      in.settings.sensor == SensorType::kMonocular || in.settings.sensor == SensorType::kMonocularInertial;
  EurocReadOptions read_options;
  read_options.require_cam1 = !single_camera;
  in.dataset = read_euroc_dataset(options.dataset, read_options);
  for (const auto& w : in.dataset.warnings) log_warn(w);
  if (single_camera) {
    ORBATLAS_CHECK(!in.dataset.cameras.empty() && !in.dataset.cameras[0].frames.empty(),
                   options.dataset << " has no cam0 images");
    for (const auto& image : in.dataset.cameras[0].frames) in.frames.push_back({image.t_ns, image.path, {}});
  } else {
    in.frames = pair_stereo_frames(in.dataset);
  }
  keep_time_window(in.frames, options.start_s, options.duration_s, options.dataset);
  return in;
}

}  // namespace orbatlas
