#pragma once
// Benchmarks behind `orbatlas bench`: each prints figures (text or one JSON object).
#include <filesystem>
#include <opencv2/core/mat.hpp>
#include <string>
#include <vector>

namespace orbatlas::cli {

// An image of a benchmark's dataset as 8-bit grey; DataError naming the file
// when it cannot be read.
cv::Mat read_gray(const std::filesystem::path& path);

struct RenderBenchOptions {
  std::string sequence = "MH_01";
  int frames = 200;
  bool json = false;

  // Throws Error naming the first value out of range.
  void check() const;
};
void run_render_bench(const RenderBenchOptions& options);

struct FeatureBenchOptions {
  std::filesystem::path dataset;
  std::filesystem::path config;      // default: config/euroc/stereo.yaml
  std::filesystem::path vocabulary;  // default: the shipped vocabulary
  int frames = 100;
  int database_keyframes = 1000;
  bool json = false;

  // Throws Error naming the first value out of range.
  void check() const;
};
void run_feature_bench(const FeatureBenchOptions& options);

struct AtlasStoreBenchOptions {
  int keyframes = 1000;
  int keypoints = 1200;              // per keyframe (EuRoC stereo settings)
  int points_per_keyframe = 60;      // new map points per keyframe, each seen by ~5 keyframes
  std::filesystem::path vocabulary;  // default: the shipped vocabulary (loading recomputes BoW with it)
  std::filesystem::path database;    // default: a temporary file, removed at the end
  // Instead of the synthetic atlas: the atlas stored here (a file or a
  // postgresql:// URI), loaded and saved into `database` (e.g. SQLite -> PostgreSQL).
  std::string from_atlas;
  bool json = false;

  // Throws Error naming the first value out of range.
  void check() const;
};
void run_atlas_store_bench(const AtlasStoreBenchOptions& options);

struct AlignmentBenchOptions {
  int problems = 2000;  // random Sim(3) problems per size
  bool json = false;

  // Throws Error naming the first value out of range.
  void check() const;
};
void run_alignment_bench(const AlignmentBenchOptions& options);

struct StereoBenchOptions {
  // Rendered with `orbatlas sim --depth --depth-noise 0`: the exact depth of
  // cam0's pixels beside the stereo images.
  std::filesystem::path dataset;
  std::filesystem::path config;  // default: config/euroc/stereo.yaml
  int frames = 40;               // spread over the dataset
  double depth_map_factor = 5000.0;
  bool json = false;

  // Throws Error naming the first value out of range.
  void check() const;
};
void run_stereo_bench(const StereoBenchOptions& options);

struct PlaceBenchOptions {
  std::filesystem::path map, queries;           // EuRoC ASL stereo datasets with ground truth in one world frame
  std::filesystem::path config;                 // default: config/euroc/stereo.yaml
  std::filesystem::path vocabulary;             // default: the shipped vocabulary
  int every = 10;                               // query every n-th frame
  double revisit_m = 0.75, revisit_deg = 20.0;  // how close to a keyframe a query must be
  bool json = false;
  bool show_progress = true;

  // Throws Error naming the first value out of range.
  void check() const;
};
void run_place_bench(const PlaceBenchOptions& options);

// p in [0, 1] of an unsorted sample (copied).
double percentile(std::vector<double> values, double p);

}  // namespace orbatlas::cli
