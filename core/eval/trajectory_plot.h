#pragma once
// A top view (x-y, equal aspect ratio) of ground truth and an aligned estimate,
// written as a PNG: two polylines, metre ticks and grid, legend and title.
#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

namespace orbatlas {

struct TrajectoryPlot {
  std::string title;  // ASCII (OpenCV's Hershey fonts)
  std::vector<Eigen::Vector3d> ground_truth;
  std::vector<Eigen::Vector3d> estimate;  // already aligned to the ground truth
  std::string ground_truth_label = "ground truth";
  std::string estimate_label = "estimate";
  int width_px = 1000;
  int height_px = 860;
};

// Throws Error when there is nothing to draw or the file cannot be written.
void write_trajectory_plot(const std::filesystem::path& png, const TrajectoryPlot& plot);

}  // namespace orbatlas
