#include "core/features/feature_grid.h"

#include <algorithm>
#include <cmath>

#include "core/common/error.h"

namespace orbatlas {

FeatureGrid::FeatureGrid(const ImageFeatures& features, int cols, int rows) : cols_(cols), rows_(rows) {
  ORBATLAS_CHECK(cols >= 1 && rows >= 1, "FeatureGrid: needs at least one cell, got " << cols << "x" << rows);
  ORBATLAS_CHECK(features.width > 0 && features.height > 0,
                 "FeatureGrid: the image size must be positive, got " << features.width << "x" << features.height);
  ORBATLAS_CHECK(features.keypoints.size() < std::size_t{0xffffffffu}, "FeatureGrid: too many keypoints");
  cells_per_px_x_ = static_cast<float>(cols) / static_cast<float>(features.width);
  cells_per_px_y_ = static_cast<float>(rows) / static_cast<float>(features.height);

  // Counting sort of the keypoints by cell.
  const auto n_cells = static_cast<std::size_t>(cols) * static_cast<std::size_t>(rows);
  cell_begin_.assign(n_cells + 1, 0);
  std::vector<std::uint32_t> cell_of(features.keypoints.size(), 0);
  std::size_t kept = 0;
  for (std::size_t i = 0; i < features.keypoints.size(); ++i) {
    const Eigen::Vector2f& uv = features.keypoints[i].uv;
    if (!std::isfinite(uv.x()) || !std::isfinite(uv.y())) {
      cell_of[i] = static_cast<std::uint32_t>(n_cells);  // left out
      continue;
    }
    cell_of[i] = static_cast<std::uint32_t>(cell_y(uv.y()) * cols_ + cell_x(uv.x()));
    ++cell_begin_[cell_of[i] + 1];
    ++kept;
  }
  for (std::size_t c = 0; c < n_cells; ++c) cell_begin_[c + 1] += cell_begin_[c];
  entries_.resize(kept);
  std::vector<std::uint32_t> fill(cell_begin_.begin(), cell_begin_.end() - 1);
  for (std::size_t i = 0; i < features.keypoints.size(); ++i) {
    if (cell_of[i] == n_cells) continue;
    const Keypoint& kp = features.keypoints[i];
    entries_[fill[cell_of[i]]++] = {kp.uv.x(), kp.uv.y(), kp.level, static_cast<std::uint32_t>(i)};
  }
}

int FeatureGrid::cell_x(float u) const {
  const float c = std::floor(u * cells_per_px_x_);
  return c < 0.0f ? 0 : (c >= static_cast<float>(cols_) ? cols_ - 1 : static_cast<int>(c));
}

int FeatureGrid::cell_y(float v) const {
  const float c = std::floor(v * cells_per_px_y_);
  return c < 0.0f ? 0 : (c >= static_cast<float>(rows_) ? rows_ - 1 : static_cast<int>(c));
}

std::vector<std::size_t> FeatureGrid::in_radius(const Eigen::Vector2f& uv, float radius, int min_level,
                                                int max_level) const {
  std::vector<std::size_t> out;
  in_radius(uv, radius, min_level, max_level, out);
  return out;
}

void FeatureGrid::in_radius(const Eigen::Vector2f& uv, float radius, int min_level, int max_level,
                            std::vector<std::size_t>& out) const {
  out.clear();
  if (entries_.empty() || !(radius >= 0.0f) || !std::isfinite(uv.x()) || !std::isfinite(uv.y())) return;
  // Cells are clamped like the keypoints were, so points outside the image are found too.
  const int x0 = cell_x(uv.x() - radius), x1 = cell_x(uv.x() + radius);
  const int y0 = cell_y(uv.y() - radius), y1 = cell_y(uv.y() + radius);
  const float r2 = radius * radius;
  const bool check_min = min_level >= 0, check_max = max_level >= 0;
  for (int cy = y0; cy <= y1; ++cy)
    for (int cx = x0; cx <= x1; ++cx) {
      const auto cell = static_cast<std::size_t>(cy * cols_ + cx);
      for (std::uint32_t k = cell_begin_[cell]; k < cell_begin_[cell + 1]; ++k) {
        const Entry& e = entries_[k];
        if ((check_min && e.level < min_level) || (check_max && e.level > max_level)) continue;
        const float du = e.u - uv.x(), dv = e.v - uv.y();
        if (du * du + dv * dv <= r2) out.push_back(e.index);
      }
    }
}

}  // namespace orbatlas
