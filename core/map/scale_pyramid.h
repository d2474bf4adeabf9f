#pragma once
// The image pyramid's scale levels as the map sees them: the distance range over
// which a point keeps its appearance, and the level it should be found at.
#include <algorithm>
#include <cmath>
#include <vector>

namespace orbatlas {

struct ScalePyramid {
  double scale_factor = 1.2;
  int n_levels = 8;

  double scale(int level) const { return std::pow(scale_factor, level); }
  double sigma2(int level) const { return std::pow(scale_factor, 2 * level); }
  std::vector<double> level_sigma2() const {
    std::vector<double> out(static_cast<std::size_t>(n_levels));
    for (int l = 0; l < n_levels; ++l) out[static_cast<std::size_t>(l)] = sigma2(l);
    return out;
  }
  // ORB-SLAM's PredictScale: the level a point at `distance` is expected on, given
  // the largest distance it is invariant to.
  int predict_level(double distance, double max_distance) const {
    const double ratio = max_distance / std::max(distance, 1e-9);
    const int level = static_cast<int>(std::ceil(std::log(ratio) / std::log(scale_factor)));
    return std::clamp(level, 0, n_levels - 1);
  }
};

}  // namespace orbatlas
