// orbatlas bench stereo: the depth our stereo matching gives a frame's keypoints
// against the exact depth the simulator rendered (`orbatlas sim --depth
// --depth-noise 0`), per depth band: the disparity error's mean (its bias),
// median and spread, and the depth scale the bias amounts to. A disparity
// biased by a few hundredths of a pixel is invisible in the spread but makes far
// points systematically nearer or farther, so a map built from them is smaller
// or larger than the world.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgcodecs.hpp>

#include "client/benchmarks.h"
#include "core/camera/camera_factory.h"
#include "core/common/data_paths.h"
#include "core/common/error.h"
#include "core/common/progress.h"
#include "core/io/settings.h"
#include "core/io/tum_rgbd.h"
#include "core/tracking/stereo_frontend.h"

namespace orbatlas::cli {
namespace {

// mav0/cam0/data/<t>.png -> mav0/cam1/data/<t>.png
std::filesystem::path right_image_of(const std::filesystem::path& left) {
  const auto data = left.parent_path();
  const auto cam0 = data.parent_path();
  ORBATLAS_CHECK(cam0.filename() == "cam0",
                 "bench stereo: " << left.string() << " is not a cam0 image of an ASL layout");
  return cam0.parent_path() / "cam1" / data.filename() / left.filename();
}

// The depth [m] at sub-pixel (u, v), bilinear, when the 4x4 pixels around it
// all have depth within 1 % of each other (no depth edge); nullopt otherwise.
std::optional<double> smooth_depth_at(const cv::Mat& depth16, double factor, const Eigen::Vector2d& uv) {
  const int u0 = static_cast<int>(std::floor(uv.x())) - 1, v0 = static_cast<int>(std::floor(uv.y())) - 1;
  if (u0 < 0 || v0 < 0 || u0 + 3 >= depth16.cols || v0 + 3 >= depth16.rows) return std::nullopt;
  int lo = 65535, hi = 0;
  for (int v = v0; v <= v0 + 3; ++v)
    for (int u = u0; u <= u0 + 3; ++u) {
      const int d = depth16.at<std::uint16_t>(v, u);
      lo = std::min(lo, d);
      hi = std::max(hi, d);
    }
  if (lo == 0 || hi > lo * 1.01) return std::nullopt;
  const double fu = uv.x() - std::floor(uv.x()), fv = uv.y() - std::floor(uv.y());
  const int u = u0 + 1, v = v0 + 1;
  auto at = [&](int dv, int du) { return static_cast<double>(depth16.at<std::uint16_t>(v + dv, u + du)); };
  const double top = at(0, 0) * (1 - fu) + at(0, 1) * fu, bottom = at(1, 0) * (1 - fu) + at(1, 1) * fu;
  return (top * (1 - fv) + bottom * fv) / factor;
}

struct Band {
  double near_m, far_m;
  std::vector<double> disparity_error;  // measured - true [px]
  std::vector<double> depth_ratio;      // measured / true
};

nlohmann::json band_json(const Band& b) {
  nlohmann::json j = {{"near_m", b.near_m}, {"far_m", b.far_m}, {"keypoints", b.disparity_error.size()}};
  if (b.disparity_error.empty()) return j;
  std::vector<double> e = b.disparity_error;
  const double n = static_cast<double>(e.size());
  double mean = 0.0, ratio = 0.0;
  for (const double x : e) mean += x / n;
  for (const double r : b.depth_ratio) ratio += r / n;
  double var = 0.0;
  for (const double x : e) var += (x - mean) * (x - mean) / n;
  std::nth_element(e.begin(), e.begin() + static_cast<std::ptrdiff_t>(e.size() / 2), e.end());
  j["mean_px"] = mean;
  j["mean_stderr_px"] = std::sqrt(var / n);
  j["median_px"] = e[e.size() / 2];
  j["std_px"] = std::sqrt(var);
  j["depth_scale"] = ratio;  // the mean measured / true depth
  return j;
}

}  // namespace

void run_stereo_bench(const StereoBenchOptions& o) {
  o.check();
  const auto config = o.config.empty() ? shipped_config_dir() / "euroc" / "stereo.yaml" : o.config;
  const SlamSettings settings = read_settings(config, SensorType::kStereo);
  ORBATLAS_CHECK(settings.camera1.has_value(), "bench stereo needs a stereo configuration: " << config.string());
  if (!std::filesystem::exists(o.dataset / "depth.txt"))
    throw DataError("bench stereo: " + o.dataset.string() +
                    " has no depth.txt; render it with `orbatlas sim --depth --depth-noise 0`");
  const TumRgbdDataset dataset = read_tum_rgbd(o.dataset);
  ORBATLAS_CHECK(!dataset.frames.empty(), "bench stereo: no frames with depth in " << o.dataset.string());

  StereoFrontend frontend(settings);
  const auto cam0 = make_camera(settings.camera0);
  // Rectified left camera -> cam0 (a rotation: both at the left optical centre).
  const Pose3 T_c0_rect = settings.camera0.T_b_c.inverse() * frontend.calibration().T_b_c;
  const double bf = frontend.bf();
  std::vector<Band> bands{{0, 2, {}, {}}, {2, 4, {}, {}}, {4, 6, {}, {}}, {6, 10, {}, {}}, {10, 1e9, {}, {}}};
  Band all{0, 1e9, {}, {}};
  std::size_t stereo_keypoints = 0, frames_used = 0;

  const std::size_t n = std::min<std::size_t>(dataset.frames.size(), static_cast<std::size_t>(o.frames));
  Progress progress("bench stereo", static_cast<std::int64_t>(n));
  for (std::size_t k = 0; k < n; ++k) {
    const RgbdFrame& rf = dataset.frames[k * dataset.frames.size() / n];
    const cv::Mat left = read_gray(rf.rgb), right = read_gray(right_image_of(rf.rgb));
    const cv::Mat depth16 = read_depth_image(rf.depth, left.cols, left.rows);
    const Frame frame = frontend.make_frame(rf.t_ns, left, right);
    ++frames_used;
    for (std::size_t i = 0; i < frame.size(); ++i) {
      const double z = frame.depth[i];
      if (z <= 0.0) continue;
      ++stereo_keypoints;
      const Eigen::Vector3d& bearing = frame.features.keypoints[i].bearing;
      const Eigen::Vector3d p_c0 = T_c0_rect * (bearing * (z / bearing.z()));
      Eigen::Vector2d uv;
      if (p_c0.z() <= 0.0 || !cam0->project(p_c0, &uv)) continue;
      const auto truth = smooth_depth_at(depth16, o.depth_map_factor, uv);
      if (!truth) continue;
      // Along one ray, depths in both frames scale alike.
      const double ratio = p_c0.z() / *truth;
      const double disparity = bf / z, true_disparity = bf / (z / ratio);
      const double error = disparity - true_disparity;
      if (std::abs(error) > 2.0) continue;  // a wrong match, not the matching's precision
      const double true_z = z / ratio;
      for (Band& b : bands)
        if (true_z >= b.near_m && true_z < b.far_m) {
          b.disparity_error.push_back(error);
          b.depth_ratio.push_back(ratio);
        }
      all.disparity_error.push_back(error);
      all.depth_ratio.push_back(ratio);
    }
    progress.advance();
  }
  progress.finish();

  nlohmann::json out = {{"dataset", o.dataset.string()},
                        {"frames", frames_used},
                        {"stereo_keypoints", stereo_keypoints},
                        {"bf", bf},
                        {"all", band_json(all)},
                        {"bands", nlohmann::json::array()}};
  for (const Band& b : bands) out["bands"].push_back(band_json(b));
  if (o.json) {
    std::printf("%s\n", out.dump(2).c_str());
    return;
  }
  std::printf("stereo depth against rendered depth: %s, %zu frames, %zu stereo keypoints (%zu checked)\n",
              o.dataset.string().c_str(), frames_used, stereo_keypoints, all.disparity_error.size());
  std::printf("%-10s %8s %12s %10s %9s %12s\n", "depth [m]", "points", "bias [px]", "median", "std", "depth scale");
  auto row = [](const char* name, const nlohmann::json& j) {
    if (j["keypoints"].get<std::size_t>() == 0) return;
    std::printf("%-10s %8zu %+7.4f±%.4f %+10.4f %9.3f %12.4f\n", name, j["keypoints"].get<std::size_t>(),
                j["mean_px"].get<double>(), j["mean_stderr_px"].get<double>(), j["median_px"].get<double>(),
                j["std_px"].get<double>(), j["depth_scale"].get<double>());
  };
  for (const auto& j : out["bands"]) {
    char name[32];
    const double far = j["far_m"].get<double>();
    if (far > 1e8)
      std::snprintf(name, sizeof name, ">= %.0f", j["near_m"].get<double>());
    else
      std::snprintf(name, sizeof name, "%.0f-%.0f", j["near_m"].get<double>(), far);
    row(name, j);
  }
  row("all", out["all"]);
}

}  // namespace orbatlas::cli
