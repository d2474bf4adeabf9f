#pragma once
// A top view (x-y, equal aspect ratio) of trajectories, written as a PNG: each
// estimate its own polyline and colour, the ground truth dashed, metre ticks
// and grid, a legend naming each line, a title. Lines are never joined: several
// sessions are several lines.
#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

namespace orbatlas {

struct PlotLine {
  std::string label;  // ASCII (OpenCV's Hershey fonts); shown in the legend
  std::vector<Eigen::Vector3d> points;
};

struct TrajectoryPlot {
  std::string title;  // ASCII
  // Dashed, one colour, one legend entry ("ground truth") for all of them:
  // e.g. the ground truth over each session's span.
  std::vector<std::vector<Eigen::Vector3d>> ground_truth;
  std::vector<PlotLine> estimates;  // already aligned to the ground truth; a colour each
  std::string ground_truth_label = "ground truth";
  int width_px = 1000;
  int height_px = 860;
};

// The axes' area in the image (pixels): the data is centred in it.
struct PlotArea {
  int x = 0, y = 0, width = 0, height = 0;
};
PlotArea trajectory_plot_area(int width_px, int height_px);

// Throws Error when there is nothing to draw or the file cannot be written.
void write_trajectory_plot(const std::filesystem::path& png, const TrajectoryPlot& plot);

}  // namespace orbatlas
