#pragma once
// A uniform grid of cells over an image holding keypoint indices, for finding the
// keypoints near a position (radius search), as ORB-SLAM's frame grid.
#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/features/keypoint.h"

namespace orbatlas {

class FeatureGrid {
 public:
  static constexpr int kDefaultCols = 64, kDefaultRows = 48;

  FeatureGrid() = default;  // an empty grid: every search finds nothing
  // Over [0, width) x [0, height) of `features` (which must be > 0), from the
  // keypoints' detected positions uv. Keypoints outside the image go to the
  // nearest border cell (they are still found); non-finite positions are left out.
  // The grid copies what it needs (uv, level): `features` may go away.
  explicit FeatureGrid(const ImageFeatures& features, int cols = kDefaultCols, int rows = kDefaultRows);

  // Indices of the keypoints with |uv_i - uv| <= radius (a disc, not a square
  // window) and, for each bound given (>= 0), min_level <= level_i <= max_level.
  // Cell by cell, ascending within a cell. Empty for a negative radius or a
  // non-finite uv.
  std::vector<std::size_t> in_radius(const Eigen::Vector2f& uv, float radius, int min_level = -1,
                                     int max_level = -1) const;
  // The same into `out` (cleared first): loops reuse one buffer.
  void in_radius(const Eigen::Vector2f& uv, float radius, int min_level, int max_level,
                 std::vector<std::size_t>& out) const;

  std::size_t size() const { return entries_.size(); }  // keypoints held
  int cols() const { return cols_; }
  int rows() const { return rows_; }

 private:
  struct Entry {
    float u, v;
    int level;
    std::uint32_t index;
  };
  int cell_x(float u) const;
  int cell_y(float v) const;

  int cols_ = 0, rows_ = 0;
  float cells_per_px_x_ = 0.0f, cells_per_px_y_ = 0.0f;
  std::vector<std::uint32_t> cell_begin_;  // cols * rows + 1 offsets into entries_, row-major cells
  std::vector<Entry> entries_;             // grouped by cell
};

}  // namespace orbatlas
