#include "core/server/uploaded_recording.h"

#include "core/common/error.h"
#include "core/io/kitti_odometry.h"
#include "core/io/tum_rgbd.h"
#include "core/io/tum_trajectory.h"
#include "core/persistence/map_rigs.h"

namespace orbatlas {
namespace {

namespace fs = std::filesystem;

bool is_recording(const fs::path& dir) {
  return fs::is_directory(dir / "mav0") || fs::is_regular_file(dir / "rgb.txt") || is_kitti_sequence(dir);
}

}  // namespace

fs::path uploaded_recording_root(const fs::path& extracted) {
  if (is_recording(extracted)) return extracted;
  std::vector<fs::path> dirs;
  for (const auto& e : fs::directory_iterator(extracted))
    if (e.is_directory()) dirs.push_back(e.path());
  if (dirs.size() == 1 && is_recording(dirs[0])) return dirs[0];
  throw DataError(
      "the archive holds no EuRoC ASL folder (mav0/), TUM RGB-D one (rgb.txt) nor KITTI odometry sequence "
      "(image_0/, times.txt, calib.txt) at its root or in its only folder");
}

UploadedRecording read_uploaded_recording(const fs::path& root, SensorType sensor) {
  UploadedRecording r;
  if (sensor == SensorType::kRgbd) {
    ORBATLAS_DATA_CHECK(fs::is_regular_file(root / "rgb.txt"),
                        "an RGB-D session's upload is a TUM RGB-D recording (rgb.txt, depth.txt, rgb/, depth/)");
    const TumRgbdDataset d = read_tum_rgbd(root, 0.02, /*confined=*/true);
    r.frames = rgbd_image_pairs(d);
    r.ground_truth = ground_truth_states(d);
    ORBATLAS_DATA_CHECK(!r.frames.empty(), "the recording has no colour image with a depth image");
    return r;
  }
  if (is_kitti_sequence(root)) {
    const KittiSequence kitti = read_kitti_sequence(root, /*confined=*/true);
    for (const DatasetFrame& f : kitti.frames)
      r.frames.push_back(is_single_camera(sensor) ? DatasetFrame{f.t_ns, f.left, {}} : f);
    r.ground_truth = ground_truth_states(kitti.ground_truth);
    return r;
  }
  ORBATLAS_DATA_CHECK(fs::is_directory(root / "mav0"),
                      "a stereo session's upload is an EuRoC ASL recording (mav0/); a TUM RGB-D one needs an rgbd "
                      "config");
  const bool single_camera = is_single_camera(sensor);
  EurocReadOptions read_options;
  read_options.require_cam1 = !single_camera;
  read_options.confined = true;
  EurocDataset dataset = read_euroc_dataset(root, read_options);
  if (single_camera) {
    ORBATLAS_DATA_CHECK(!dataset.cameras.empty(), "the recording has no cam0");
    for (const auto& image : dataset.cameras[0].frames) r.frames.push_back({image.t_ns, image.path, {}});
    r.T_b_c0 = dataset.cameras[0].calibration.T_b_c;
  } else {
    r.frames = pair_stereo_frames(dataset);
  }
  ORBATLAS_DATA_CHECK(!r.frames.empty(), "the recording has no " << (single_camera ? "images" : "stereo frames"));
  r.ground_truth = std::move(dataset.ground_truth);
  r.imu = std::move(dataset.imu);
  return r;
}

void check_uploaded_recording(const fs::path& extracted) {
  fs::path root;
  try {
    root = uploaded_recording_root(extracted);
  } catch (const DataError&) {
    return;  // no recording at all: the job says so (and keeps its id)
  }
  if (fs::is_regular_file(root / "rgb.txt")) read_tum_rgbd(root, 0.02, /*confined=*/true);
  if (is_kitti_sequence(root)) read_kitti_sequence(root, /*confined=*/true);
  if (fs::is_directory(root / "mav0")) {
    EurocReadOptions options;
    options.confined = true;
    read_euroc_dataset(root, options);
  }
}

}  // namespace orbatlas
