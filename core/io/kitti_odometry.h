#pragma once
// The KITTI odometry benchmark's layout (Geiger, Lenz, Urtasun, 2012), one
// sequence folder:
//   image_0/NNNNNN.png, image_1/NNNNNN.png  rectified grey stereo (left, right)
//   times.txt                               one time per frame, in seconds
//   calib.txt                               the rectified cameras' 3x4 projection
//                                           matrices, rows "P0: ..." (or bare rows)
// and, optionally, its ground truth: poses.txt in the folder, or the
// benchmark's dataset/poses/NN.txt beside dataset/sequences/NN/ — camera 0's
// pose in the frame of the first camera 0, one 3x4 row-major matrix per frame.
// The body frame of a KITTI session is camera 0.
#include <filesystem>
#include <string>
#include <vector>

#include "core/geometry/trajectory.h"
#include "core/io/euroc_reader.h"

namespace orbatlas {

// What calib.txt's P0 and P1 say (the rectified pair), and the images' size.
struct KittiCalibration {
  double fx = 0.0, fy = 0.0, cx = 0.0, cy = 0.0;
  double baseline_m = 0.0;  // -P1[0][3] / fx
  int width = 0, height = 0;
};

struct KittiSequence {
  std::filesystem::path root;
  std::vector<DatasetFrame> frames;  // image_0 as left, image_1 as right, times.txt's times
  KittiCalibration calibration;
  double fps = 10.0;                        // from the times (KITTI records at about 10 Hz)
  Trajectory ground_truth;                  // camera 0; empty without a poses file
  std::filesystem::path ground_truth_file;  // the poses file read, if any
};

// image_0/, times.txt and calib.txt are there.
bool is_kitti_sequence(const std::filesystem::path& dir);

// Reads the sequence. DataError (file and line) on a missing or malformed file,
// times that do not increase, a frame whose image_0 or image_1 file is missing,
// calibration that is not a rectified pair, or a poses file whose line count is
// not the frame count. `confined`: every file must lie inside `dir`
// (core/io/recording_paths.h), as for uploads.
KittiSequence read_kitti_sequence(const std::filesystem::path& dir, bool confined = false);

// A poses file (one 3x4 row-major matrix per line) with the frames' times.
Trajectory read_kitti_poses(const std::filesystem::path& path, const std::vector<TimestampNs>& times);
// The poses file of a sequence folder: its poses.txt, or ../../poses/<name>.txt;
// empty when there is none.
std::filesystem::path kitti_poses_file(const std::filesystem::path& dir);

// times.txt's times.
std::vector<TimestampNs> read_kitti_times(const std::filesystem::path& path);
// The ground truth `orbatlas eval --gt` takes in KITTI's form: a sequence
// folder (its poses file), or a poses file whose times are the times.txt beside
// it or, in the benchmark's layout (poses/NN.txt), sequences/NN/times.txt.
// DataError when there are no poses or no times.
Trajectory read_kitti_ground_truth(const std::filesystem::path& path);
// A file of 3x4 poses (12 numbers per line, spaces, no commas)?
bool looks_like_kitti_poses(const std::filesystem::path& path);

// The sequence's settings (docs/settings.md's format, so they are checked as
// any settings file is): rectified pinhole stereo from calib.txt with ORB-SLAM3's
// KITTI feature settings (2,000 features, 8 levels of 1.2, FAST 20/7, close
// points within 40 baselines).
std::string kitti_settings_yaml(const KittiSequence& sequence);

}  // namespace orbatlas
