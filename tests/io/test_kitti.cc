// The KITTI odometry layout (core/io/kitti_odometry.h) and real KITTI data in the
// suite: the excerpt in ../shared/data/kitti/excerpt_1 (51 real rectified stereo
// pairs of a car driving about 60 m, with the benchmark's ground truth; its
// README gives provenance and licence), read as it lies, with the settings
// derived from its calib.txt. Stereo SLAM over it, and its frames localised in a
// stored map built from the other frames. The tests of the real data skip with
// the reason where the folder is missing, and fail under ORBATLAS_REQUIRE=all (CI).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "core/common/data_paths.h"
#include "core/common/error.h"
#include "core/eval/evaluate.h"
#include "core/io/kitti_odometry.h"
#include "core/io/settings.h"
#include "core/io/tum_trajectory.h"
#include "core/pipeline/dataset_runner.h"
#include "tests/support/requirement.h"

namespace orbatlas {
namespace {

namespace fs = std::filesystem;

#define ORBATLAS_REQUIRE_KITTI_EXCERPT(var)                                                             \
  const std::optional<fs::path> kitti_root_ = shared_kitti_dir();                                       \
  if (!kitti_root_ || !is_kitti_sequence(*kitti_root_ / "excerpt_1"))                                   \
    ORBATLAS_NEEDS("the real KITTI excerpt (../shared/data/kitti/excerpt_1 or ORBATLAS_SHARED_KITTI)"); \
  const fs::path var = *kitti_root_ / "excerpt_1"

struct TempFolder {
  fs::path path;
  explicit TempFolder(const std::string& name)
      : path(fs::temp_directory_path() / ("orbatlas_test_kitti_" + name + "_" + std::to_string(::getpid()))) {
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempFolder() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

void write_file(const fs::path& path, const std::string& text) { std::ofstream(path, std::ios::trunc) << text; }

constexpr const char* kCalib =
    "P0: 7.070912e+02 0 6.018873e+02 0 0 7.070912e+02 1.831104e+02 0 0 0 1 0\n"
    "P1: 7.070912e+02 0 6.018873e+02 -3.798145e+02 0 7.070912e+02 1.831104e+02 0 0 0 1 0\n"
    "Tr: 1 0 0 0 0 1 0 0 0 0 1 0\n";

// A small sequence of `n` frames in the benchmark's layout (grey 64x48 images).
void write_sequence(const fs::path& dir, int n) {
  fs::create_directories(dir / "image_0");
  fs::create_directories(dir / "image_1");
  std::string times, poses;
  for (int i = 0; i < n; ++i) {
    char name[16];
    std::snprintf(name, sizeof name, "%06d.png", i);
    cv::imwrite((dir / "image_0" / name).string(), cv::Mat(48, 64, CV_8UC1, cv::Scalar(i)));
    cv::imwrite((dir / "image_1" / name).string(), cv::Mat(48, 64, CV_8UC1, cv::Scalar(i)));
    times += std::to_string(0.1 * i) + "\n";
    poses += "1 0 0 0 0 1 0 0 0 0 1 " + std::to_string(0.8 * i) + "\n";
  }
  write_file(dir / "times.txt", times);
  write_file(dir / "calib.txt", kCalib);
  write_file(dir / "poses.txt", poses);
}

std::string data_error(const fs::path& dir) {
  try {
    read_kitti_sequence(dir);
  } catch (const DataError& e) {
    return e.what();
  }
  return "";
}

TEST(KittiOdometry, ReadsTheLayoutItsCalibrationAndItsPoses) {
  TempFolder tmp("layout");
  write_sequence(tmp.path, 5);
  ASSERT_TRUE(is_kitti_sequence(tmp.path));
  const KittiSequence s = read_kitti_sequence(tmp.path);
  ASSERT_EQ(s.frames.size(), 5u);
  EXPECT_EQ(s.frames[3].t_ns, 300'000'000);
  EXPECT_EQ(s.frames[3].left, tmp.path / "image_0" / "000003.png");
  EXPECT_EQ(s.frames[3].right, tmp.path / "image_1" / "000003.png");
  EXPECT_DOUBLE_EQ(s.calibration.fx, 707.0912);
  EXPECT_DOUBLE_EQ(s.calibration.cy, 183.1104);
  EXPECT_NEAR(s.calibration.baseline_m, 379.8145 / 707.0912, 1e-12);
  EXPECT_EQ(s.calibration.width, 64);
  EXPECT_EQ(s.calibration.height, 48);
  EXPECT_NEAR(s.fps, 10.0, 1e-9);
  ASSERT_EQ(s.ground_truth.size(), 5u);
  EXPECT_NEAR(s.ground_truth[4].pose.t.z(), 3.2, 1e-12);
  EXPECT_EQ(s.ground_truth[4].t_ns, s.frames[4].t_ns);

  // The derived settings are read as any settings file is: a rectified pair.
  const SlamSettings settings = read_settings_text(kitti_settings_yaml(s), "calib.txt");
  EXPECT_EQ(settings.sensor, SensorType::kStereo);
  ASSERT_TRUE(settings.camera1.has_value());
  EXPECT_NEAR(settings.T_c0_c1.t.x(), s.calibration.baseline_m, 1e-9);
  EXPECT_EQ(settings.orb.n_features, 2000);
  EXPECT_EQ(settings.camera0.width, 64);
  // The shipped set for sequences 04-12 holds the same calibration (this calib.txt is theirs).
  const SlamSettings shipped = read_settings(shipped_config_dir() / "kitti" / "stereo_04-12.yaml");
  EXPECT_DOUBLE_EQ(shipped.camera0.fx, settings.camera0.fx);
  EXPECT_DOUBLE_EQ(shipped.camera0.cx, settings.camera0.cx);
  EXPECT_NEAR(shipped.T_c0_c1.t.x(), settings.T_c0_c1.t.x(), 1e-6);
  EXPECT_EQ(shipped.orb.n_features, settings.orb.n_features);
  for (const char* name : {"stereo_00-02.yaml", "stereo_03.yaml"})
    EXPECT_NO_THROW(read_settings(shipped_config_dir() / "kitti" / name)) << name;

  // Ground truth as `orbatlas eval --gt` takes it: the folder, or the poses
  // file with the times beside it; both the same.
  EXPECT_EQ(read_any_ground_truth(tmp.path).size(), 5u);
  const Trajectory from_file = read_any_ground_truth(tmp.path / "poses.txt");
  ASSERT_EQ(from_file.size(), 5u);
  EXPECT_EQ(from_file[2].t_ns, 200'000'000);

  // The benchmark's own layout: sequences/NN/ and poses/NN.txt.
  TempFolder bench("benchmark");
  write_sequence(bench.path / "sequences" / "07", 4);
  fs::create_directories(bench.path / "poses");
  fs::rename(bench.path / "sequences" / "07" / "poses.txt", bench.path / "poses" / "07.txt");
  EXPECT_EQ(kitti_poses_file(bench.path / "sequences" / "07"), bench.path / "poses" / "07.txt");
  EXPECT_EQ(read_kitti_sequence(bench.path / "sequences" / "07").ground_truth.size(), 4u);
  EXPECT_EQ(read_any_ground_truth(bench.path / "poses" / "07.txt").size(), 4u);
}

TEST(KittiOdometry, RefusesABrokenSequenceSayingWhere) {
  TempFolder tmp("broken");
  write_sequence(tmp.path, 4);
  write_file(tmp.path / "calib.txt", "P0: 7.07e+02 0 6.0e+02 0 0 7.07e+02 1.8e+02 0 0 0 1 0\n");
  EXPECT_NE(data_error(tmp.path).find("needs the projection matrices P0 and P1"), std::string::npos);
  write_file(tmp.path / "calib.txt",
             "P0: 7.07e+02 0 6.0e+02 0 0 7.07e+02 1.8e+02 0 0 0 1 0\nP1: 7.07e+02 0 6.0e+02 -3.8e+02 0 7.07e+02 "
             "1.9e+02 0 0 0 1 0\n");
  EXPECT_NE(data_error(tmp.path).find("not a rectified stereo pair"), std::string::npos);
  write_file(tmp.path / "calib.txt", "P0: 1 2 3\n");
  EXPECT_NE(data_error(tmp.path).find("calib.txt:1: a 3x4 projection matrix has 12 numbers, not 3"), std::string::npos);
  write_file(tmp.path / "calib.txt", kCalib);

  write_file(tmp.path / "times.txt", "0.0\n0.1\n0.1\n0.3\n");
  EXPECT_NE(data_error(tmp.path).find("times.txt:3: the time 0.1 s is not after the one before"), std::string::npos);
  write_file(tmp.path / "times.txt", "0.0\n0.1\nnan\n0.3\n");
  EXPECT_NE(data_error(tmp.path).find("times.txt:3"), std::string::npos);
  write_file(tmp.path / "times.txt", "0.0\n0.1\n0.2\n0.3\n0.4\n");
  EXPECT_NE(data_error(tmp.path).find("frame 4 (times.txt line 5) has no"), std::string::npos);
  write_file(tmp.path / "times.txt", "0.0\n0.1\n0.2\n");
  EXPECT_NE(data_error(tmp.path).find("poses.txt:4: more poses than the 3 times of the sequence"), std::string::npos);
  write_file(tmp.path / "times.txt", "0.0\n0.1\n0.2\n0.3\n");
  write_file(tmp.path / "poses.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n");
  EXPECT_NE(data_error(tmp.path).find("poses.txt: 1 poses for 4 frames"), std::string::npos);
  write_file(tmp.path / "times.txt", "0.0\n0.1\n0.2\n0.3\n");
  write_file(tmp.path / "poses.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n2 0 0 0 0 1 0 0 0 0 1 0\n");
  EXPECT_NE(data_error(tmp.path).find("poses.txt:2: the 3x3 part is not a rotation"), std::string::npos);
  fs::remove(tmp.path / "calib.txt");
  EXPECT_FALSE(is_kitti_sequence(tmp.path));
  EXPECT_NE(data_error(tmp.path).find("is not a KITTI odometry sequence"), std::string::npos);
}

// Every `step`-th frame of `from` (from `first` on) as a sequence of its own:
// links to the images, their times and poses.
void write_every_other(const fs::path& from, const fs::path& to, int first) {
  const KittiSequence s = read_kitti_sequence(from);
  fs::create_directories(to / "image_0");
  fs::create_directories(to / "image_1");
  fs::copy_file(from / "calib.txt", to / "calib.txt");
  std::ofstream times(to / "times.txt"), poses(to / "poses.txt");
  times.precision(12);
  poses.precision(12);
  int n = 0;
  for (std::size_t i = static_cast<std::size_t>(first); i < s.frames.size(); i += 2, ++n) {
    char name[16];
    std::snprintf(name, sizeof name, "%06d.png", n);
    fs::create_symlink(fs::absolute(s.frames[i].left), to / "image_0" / name);
    fs::create_symlink(fs::absolute(s.frames[i].right), to / "image_1" / name);
    times << ns_to_s(s.frames[i].t_ns) << "\n";
    const Eigen::Matrix4d T = s.ground_truth[i].pose.matrix();
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) poses << T(r, c) << (r == 2 && c == 3 ? "\n" : " ");
  }
}

DatasetRunOptions kitti_run(const fs::path& dataset) {
  DatasetRunOptions o;
  o.dataset = dataset;  // no settings: calib.txt's
  o.show_progress = false;
  return o;
}

TEST(KittiReal, StereoSlamTracksEveryFrameOfTheExcerpt) {
  ORBATLAS_REQUIRE_KITTI_EXCERPT(excerpt);
  const KittiSequence sequence = read_kitti_sequence(excerpt);
  ASSERT_EQ(sequence.frames.size(), 51u);
  ASSERT_EQ(sequence.ground_truth.size(), 51u);
  const DatasetRunReport report = run_dataset(kitti_run(excerpt));
  EXPECT_EQ(report.stats.frames, 51u);
  EXPECT_EQ(report.trajectory.size(), 51u) << "every frame tracked";
  EXPECT_EQ(report.stats.maps, 1u);

  EvalOptions se3;
  se3.segment_lengths_m = std::vector<double>{};
  const EvalResult r = evaluate_trajectory(report.trajectory, sequence.ground_truth, se3);
  EvalOptions sim3;
  sim3.align = AlignMode::kSim3;
  const EvalResult s = evaluate_trajectory(report.trajectory, sequence.ground_truth, sim3);
  ASSERT_TRUE(r.segments.has_value());
  // Measured: ATE 0.0623 m, scale 0.9969, 0.83 % and 0.018 deg/m over 26 segments of 6-48 m.
  EXPECT_LT(r.ate.rmse, 0.12);
  EXPECT_NEAR(s.alignment.scale, 1.0, 0.006);
  EXPECT_GT(r.segments->segments, 20u);
  EXPECT_LT(r.segments->trans_percent, 1.6);
  EXPECT_LT(r.segments->rot_deg_per_m, 0.036);
}

// A map of the even frames is stored, then the odd frames are localised in it
// from the database (no keyframe added): each where the map's own trajectory
// says it passed (the map's frame is the first camera's, as the poses'), and
// as close to the ground truth as the map itself is.
TEST(KittiReal, ItsFramesLocaliseInAStoredMapBuiltFromTheOthers) {
  ORBATLAS_REQUIRE_KITTI_EXCERPT(excerpt);
  TempFolder tmp("localise");
  write_every_other(excerpt, tmp.path / "even", 0);
  write_every_other(excerpt, tmp.path / "odd", 1);
  DatasetRunOptions map = kitti_run(tmp.path / "even");
  map.atlas = tmp.path / "atlas.db";
  const DatasetRunReport mapped = run_dataset(map);
  ASSERT_EQ(mapped.trajectory.size(), 26u);
  ASSERT_TRUE(mapped.session.has_value());

  DatasetRunOptions localise = kitti_run(tmp.path / "odd");
  localise.atlas = map.atlas;
  localise.localize_only = true;
  const DatasetRunReport localised = run_dataset(localise);
  EXPECT_EQ(localised.loaded_maps, 1u);
  EXPECT_EQ(localised.stats.keyframes_made, 0u) << "localisation adds nothing to the stored map";
  EXPECT_EQ(localised.trajectory.size(), 25u);
  // Against the map's trajectory (the even frames, 0.2 s apart: interpolated
  // across the car's 2.4 m between them), in the map's frame, no alignment.
  EvalOptions none;
  none.align = AlignMode::kNone;
  EvalOptions on_map = none;
  on_map.association.max_gap_ns = 250'000'000;
  const EvalResult m = evaluate_trajectory(localised.trajectory, mapped.trajectory, on_map);
  const Trajectory truth = read_kitti_sequence(tmp.path / "odd").ground_truth;
  const EvalResult r = evaluate_trajectory(localised.trajectory, truth);
  const EvalResult unaligned = evaluate_trajectory(localised.trajectory, truth, none);
  const EvalResult map_unaligned =
      evaluate_trajectory(mapped.trajectory, read_kitti_sequence(tmp.path / "even").ground_truth, none);
  // Measured: 0.0065 m from the map (max 0.018); ATE 0.065 m; unaligned 0.366 m, the map's own 0.370 m.
  EXPECT_LT(m.ate.rmse, 0.013);
  EXPECT_LT(r.ate.rmse, 0.13);
  EXPECT_LT(unaligned.ate.rmse, map_unaligned.ate.rmse * 1.2);
}

}  // namespace
}  // namespace orbatlas
