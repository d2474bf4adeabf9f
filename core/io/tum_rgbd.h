#pragma once
// The TUM RGB-D dataset layout (Sturm et al., 2012): `rgb.txt` and `depth.txt`
// list "timestamp filename" per line (seconds; '#' comments), the images live in
// `rgb/` and `depth/` (16-bit PNG, a pixel's value / the depth map factor in
// metres, 0 where there is no depth), `groundtruth.txt` is a TUM trajectory.
// Colour and depth images are not taken at the same instants: each colour image
// is paired with the nearest depth image in time (TUM's associate.py, 0.02 s).
#include <filesystem>
#include <opencv2/core/mat.hpp>
#include <optional>
#include <string>
#include <vector>

#include "core/common/timestamp.h"
#include "core/geometry/trajectory.h"
#include "core/io/euroc_reader.h"

namespace orbatlas {

struct RgbdFrame {
  TimestampNs t_ns = 0;        // the colour image's
  TimestampNs depth_t_ns = 0;  // the depth image paired with it
  std::filesystem::path rgb, depth;
};

struct TumRgbdDataset {
  std::filesystem::path root;
  std::vector<RgbdFrame> frames;  // in time order
  Trajectory ground_truth;        // empty without groundtruth.txt
  std::size_t unpaired = 0;       // colour images without a depth image within max_dt
};

// Reads the lists and pairs the images. DataError (file and line) on a missing
// list, a malformed line, timestamps that do not increase, or a listed file
// that does not exist; a colour image without depth within max_dt_s is skipped
// (counted in `unpaired`). `confined`: every listed file must lie inside `dir`
// (core/io/recording_paths.h), as for uploads.
TumRgbdDataset read_tum_rgbd(const std::filesystem::path& dir, double max_dt_s = 0.02, bool confined = false);

// The frames as image pairs (the colour image, its depth image: what the
// frame loader and the runners take) and the ground truth as body states.
std::vector<DatasetFrame> rgbd_image_pairs(const TumRgbdDataset& dataset);
std::vector<GroundTruthState> ground_truth_states(const TumRgbdDataset& dataset);

// Keeps the frames from `start_s` after the first one, for `duration_s` (all
// when absent). Throws Error when none is left.
void keep_time_window(std::vector<RgbdFrame>& frames, double start_s, std::optional<double> duration_s,
                      const std::filesystem::path& dataset);

// Reads a depth image: CV_16UC1 of `width` x `height`. DataError otherwise.
cv::Mat read_depth_image(const std::filesystem::path& path, int width, int height);

// Writes rgb.txt, depth.txt (the frames' paths relative to `dir`; timestamps
// with 9 decimals: exact) and, when not empty, groundtruth.txt. The images are
// the caller's (the simulator lists its cam0 images and writes the depth).
void write_tum_rgbd_lists(const std::filesystem::path& dir, const std::vector<RgbdFrame>& frames,
                          const Trajectory& ground_truth);

// Writes a dataset in the layout above, images included.
class TumRgbdWriter {
 public:
  // `dir` must not hold rgb.txt yet (an existing dataset is never overwritten).
  explicit TumRgbdWriter(const std::filesystem::path& dir);
  // image: CV_8UC1 or CV_8UC3; depth: CV_16UC1 of the same size.
  void add(TimestampNs t_ns, const cv::Mat& image, TimestampNs depth_t_ns, const cv::Mat& depth);
  // Writes the lists (and groundtruth.txt when `ground_truth` is not empty).
  void finish(const Trajectory& ground_truth);

 private:
  std::filesystem::path dir_;
  std::vector<RgbdFrame> frames_;
};

}  // namespace orbatlas
