#pragma once
#include <filesystem>
#include <optional>

#include "core/io/euroc_types.h"

namespace orbatlas {

struct EurocReadOptions {
  bool require_cam1 = false;  // stereo use: a missing cam1 is an error
  bool require_imu = false;   // inertial use: a missing imu0 is an error
  // Every image a data.csv names must lie inside the dataset folder
  // (core/io/recording_paths.h): uploads.
  bool confined = false;
};

// Reads an EuRoC ASL dataset. `dir` may be the dataset folder or its mav0/.
// Errors (DataError, with file and line): missing mav0/cam0, unreadable or
// malformed csv/yaml, duplicate or decreasing timestamps in a csv.
// Documented skips (logged, and listed in EurocDataset::warnings): csv rows whose
// image file does not exist. cam0/cam1 frames are not paired here.
EurocDataset read_euroc_dataset(const std::filesystem::path& dir, const EurocReadOptions& options = {});

// Pairs of cam0/cam1 frames with equal timestamps (|dt| <= tolerance).
struct DatasetFrame {
  TimestampNs t_ns = 0;
  std::filesystem::path left, right;
};
std::vector<DatasetFrame> pair_stereo_frames(const EurocDataset& dataset, TimestampNs tolerance_ns = 1000);
// Keeps the frames from `start_s` after the first one, for `duration_s` (all
// when absent). Throws Error when none is left (the message names `dataset`).
void keep_time_window(std::vector<DatasetFrame>& frames, double start_s, std::optional<double> duration_s,
                      const std::filesystem::path& dataset);

// The ground-truth trajectory of state_groundtruth_estimate0/data.csv, or of a
// standalone ASL ground-truth csv file.
std::vector<GroundTruthState> read_asl_ground_truth_csv(const std::filesystem::path& csv);

}  // namespace orbatlas
