// ORB extraction the ORB-SLAM way. Per level: FAST on a grid of ~35 px cells
// (ini_th_fast, then min_th_fast where a cell gives nothing), a quadtree that keeps
// the strongest corner of each node until the level's share of the features is
// reached, orientation by intensity centroid, and rotated BRIEF (OpenCV's, bit
// for bit: rotated_brief.h) on the Gaussian-blurred level image. docs/features.md describes the design.
#include "core/features/orb_extractor.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <opencv2/imgproc.hpp>

#include "core/common/error.h"
#include "core/features/fast_kernels.h"

namespace orbatlas {
namespace {

constexpr int kBorder = OrbExtractor::kPyramidBorder;
constexpr int kFastRadius = 3;  // FAST's circle; cv::FAST detects nothing closer to a window's edge

// OpenCV's BORDER_REFLECT_101 for an index just outside [0, n).
int reflect101(int i, int n) { return cv::borderInterpolate(i, n, cv::BORDER_REFLECT_101); }

// Fills the kBorder pixels around the interior of `whole` by reflection, like
// cv::copyMakeBorder(BORDER_REFLECT_101) but in place.
void fill_border(cv::Mat& whole) {
  const int w = whole.cols - 2 * kBorder, h = whole.rows - 2 * kBorder;
  int left[kBorder], right[kBorder];
  for (int k = 0; k < kBorder; ++k) {
    left[k] = reflect101(-1 - k, w);
    right[k] = reflect101(w + k, w);
  }
  for (int y = kBorder; y < kBorder + h; ++y) {
    std::uint8_t* row = whole.ptr<std::uint8_t>(y) + kBorder;
    for (int k = 0; k < kBorder; ++k) {
      row[-1 - k] = row[left[k]];
      row[w + k] = row[right[k]];
    }
  }
  const auto cols = static_cast<std::size_t>(whole.cols);
  for (int k = 0; k < kBorder; ++k) {
    std::memcpy(whole.ptr(kBorder - 1 - k), whole.ptr(kBorder + reflect101(-1 - k, h)), cols);
    std::memcpy(whole.ptr(kBorder + h + k), whole.ptr(kBorder + reflect101(h + k, h)), cols);
  }
}

// ORB-SLAM's FAST windows on a level of `size`: cells of about cell_size over
// [min, max) of the level, each window 3 px wider on every side than its cell.
// cv::FAST finds nothing in a window's outer 3 px, so the detection areas of the
// cells tile [kBorder, size - kBorder). Empty edges for a level too small.
OrbExtractor::LevelCells level_cells(cv::Size size, int cell_size) {
  OrbExtractor::LevelCells cells;
  const int min_x = kBorder - kFastRadius, min_y = kBorder - kFastRadius;
  const int max_x = size.width - kBorder + kFastRadius, max_y = size.height - kBorder + kFastRadius;
  const int width = max_x - min_x, height = max_y - min_y;
  if (width < 2 * kFastRadius + 1 || height < 2 * kFastRadius + 1) return cells;
  const int n_cols = std::max(1, width / cell_size), n_rows = std::max(1, height / cell_size);
  const int cell_w = (width + n_cols - 1) / n_cols, cell_h = (height + n_rows - 1) / n_rows;
  const auto edges = [](int first, int cell, int n, int max) {
    // Cell i from first + i * cell, 2 * kFastRadius wider, cut at max.
    std::vector<int> e;
    for (int i = 0; i < n; ++i) {
      const int w0 = first + i * cell;
      if (w0 >= max - 2 * kFastRadius) break;
      if (e.empty()) e.push_back(w0 + kFastRadius);
      e.push_back(std::min(w0 + cell + 2 * kFastRadius, max) - kFastRadius);
    }
    return e;
  };
  cells.x_edges = edges(min_x, cell_w, n_cols, max_x);
  cells.y_edges = edges(min_y, cell_h, n_rows, max_y);
  const auto cols = static_cast<std::size_t>(size.width);
  cells.left_in_cell.assign(cols + 64, 0xff);
  cells.right_in_cell.assign(cols + 64, 0xff);
  for (std::size_t j = 0; j + 1 < cells.x_edges.size(); ++j) {
    cells.left_in_cell[static_cast<std::size_t>(cells.x_edges[j])] = 0;
    cells.right_in_cell[static_cast<std::size_t>(cells.x_edges[j + 1] - 1)] = 0;
  }
  return cells;
}

}  // namespace

void OrbExtractorOptions::check() const {
  ORBATLAS_CHECK(n_features >= 1, "ORB: n_features must be at least 1, got " << n_features);
  ORBATLAS_CHECK(std::isfinite(scale_factor) && scale_factor > 1.0 && scale_factor <= 4.0,
                 "ORB: scale_factor must be in (1, 4], got " << scale_factor);
  ORBATLAS_CHECK(n_levels >= 1 && n_levels <= 32, "ORB: n_levels must be in [1, 32], got " << n_levels);
  ORBATLAS_CHECK(ini_th_fast >= 1 && ini_th_fast <= 254, "ORB: ini_th_fast must be in [1, 254], got " << ini_th_fast);
  ORBATLAS_CHECK(min_th_fast >= 1 && min_th_fast <= ini_th_fast,
                 "ORB: min_th_fast must be in [1, ini_th_fast = " << ini_th_fast << "], got " << min_th_fast);
  ORBATLAS_CHECK(cell_size >= 8 && cell_size <= 1000, "ORB: cell_size must be in [8, 1000] pixels, got " << cell_size);
}

OrbExtractor::OrbExtractor(const OrbExtractorOptions& options) : options_(options) {
  options_.check();
  const auto levels = static_cast<std::size_t>(options_.n_levels);
  scale_factors_.resize(levels);
  level_sigma2_.resize(levels);
  scale_factors_[0] = 1.0;
  for (std::size_t l = 1; l < levels; ++l) scale_factors_[l] = scale_factors_[l - 1] * options_.scale_factor;
  for (std::size_t l = 0; l < levels; ++l) level_sigma2_[l] = scale_factors_[l] * scale_factors_[l];

  // Features per level in geometric proportion to the level area (ratio 1/s^2);
  // the last level takes the remainder so that the shares sum to n_features.
  const double ratio = 1.0 / (options_.scale_factor * options_.scale_factor);
  double share = options_.n_features * (1.0 - ratio) / (1.0 - std::pow(ratio, options_.n_levels));
  features_per_level_.resize(levels);
  int assigned = 0;
  for (std::size_t l = 0; l + 1 < levels; ++l) {
    features_per_level_[l] = static_cast<int>(std::lround(share));
    assigned += features_per_level_[l];
    share *= ratio;
  }
  features_per_level_[levels - 1] = std::max(options_.n_features - assigned, 0);

  pyramid_.resize(levels);
  bordered_.resize(levels);
}

void OrbExtractor::build_pyramid(const cv::Mat& image) {
  if (image.size() != pyramid_size_) {
    for (std::size_t l = 0; l < pyramid_.size(); ++l) {
      const float inv = static_cast<float>(1.0 / scale_factors_[l]);
      const cv::Size sz(cvRound(static_cast<float>(image.cols) * inv), cvRound(static_cast<float>(image.rows) * inv));
      ORBATLAS_CHECK(sz.width >= 1 && sz.height >= 1, "ORB: a " << image.cols << "x" << image.rows
                                                                << " image is too small for " << pyramid_.size()
                                                                << " levels");
      bordered_[l].create(sz.height + 2 * kBorder, sz.width + 2 * kBorder, CV_8UC1);
      pyramid_[l] = bordered_[l](cv::Rect(kBorder, kBorder, sz.width, sz.height));
    }
    shrink_.assign(pyramid_.size(), LinearResize());
    for (std::size_t l = 1; l < pyramid_.size(); ++l)
      shrink_[l] = LinearResize(pyramid_[l - 1].size(), pyramid_[l].size());
    cells_.resize(pyramid_.size());
    for (std::size_t l = 0; l < pyramid_.size(); ++l) cells_[l] = level_cells(pyramid_[l].size(), options_.cell_size);
    level_ratios_.clear();
    for (const cv::Mat& level : pyramid_)
      level_ratios_.emplace_back(static_cast<float>(image.cols) / static_cast<float>(level.cols),
                                 static_cast<float>(image.rows) / static_cast<float>(level.rows));
    blur_buffer_.create(image.size(), CV_8UC1);
    pyramid_size_ = image.size();
  }
  image.copyTo(pyramid_[0]);
  fill_border(bordered_[0]);
  for (std::size_t l = 1; l < pyramid_.size(); ++l) {
    // Each level from the one before, as ORB-SLAM (cv::resize, INTER_LINEAR, bit
    // for bit): the interior only (it never reads outside its source), the border
    // filled afterwards.
    shrink_[l](pyramid_[l - 1], pyramid_[l], options_.use_avx2);
    fill_border(bordered_[l]);
  }
}

void OrbExtractor::detect_level(int level) {
  const cv::Mat& img = pyramid_[static_cast<std::size_t>(level)];
  candidates_.clear();
  // The cells, their edges and masks (level_cells, once per image size).
  const LevelCells& cells = cells_[static_cast<std::size_t>(level)];
  const std::vector<int>& cell_x = cells.x_edges;
  const std::vector<int>& cell_y = cells.y_edges;
  if (cell_x.empty() || cell_y.empty()) return;  // a level too small for one cell
  const int min_x = kBorder - kFastRadius, min_y = kBorder - kFastRadius;

  // Scores of the whole detection area once, at ini_th_fast: 32-pixel blocks
  // where no pixel passes FAST's quick test at that threshold are skipped, and
  // at 20 most are. The cells then only threshold them; a cell with no corner
  // at ini_th_fast has its own area scored again at min_th_fast. Scores at or
  // above ini_th_fast are the same either way, so the cells around see the same.
  scores_.resize(static_cast<std::size_t>(img.rows) * static_cast<std::size_t>(img.cols));
  const auto stride = static_cast<std::size_t>(img.cols);
  scores_stride_ = stride;
  std::ptrdiff_t offsets[16];
  fast_circle_offsets(static_cast<std::ptrdiff_t>(img.step1()), offsets);
  for (int y = kBorder; y < img.rows - kBorder; ++y)
    fast_score_row(img.ptr<std::uint8_t>(y), offsets, kBorder, img.cols - kBorder, scores_.data() + y * stride,
                   options_.ini_th_fast, options_.use_avx2);
  const auto rescore = [&](const cv::Rect& area) {
    for (int y = area.y; y < area.y + area.height; ++y)
      fast_score_row(img.ptr<std::uint8_t>(y), offsets, area.x, area.x + area.width, scores_.data() + y * stride,
                     options_.min_th_fast, options_.use_avx2);
  };

  const auto cols = static_cast<std::size_t>(img.cols);
  zero_row_.assign(cols + 64, 0);
  band_words_ = cols / 64 + 2;
  // Candidates keep their detection index in 24 bits, and there is at most
  // one corner in each 2 x 2 block of pixels.
  ORBATLAS_CHECK(cols * static_cast<std::size_t>(img.rows) / 4 < (std::size_t{1} << 24),
                 "ORB: a " << img.cols << "x" << img.rows << " image is too large");
  if (candidates_.capacity() < cols * static_cast<std::size_t>(img.rows) / 4)
    candidates_.reserve(cols * static_cast<std::size_t>(img.rows) / 4);  // at most a corner in each 2 x 2 block

  for (std::size_t i = 0; i + 1 < cell_y.size(); ++i) {
    const int y0 = cell_y[i], y1 = cell_y[i + 1];
    band_bits_.assign(static_cast<std::size_t>(y1 - y0) * band_words_, 0);
    band_maxima(cells, y0, y1, cell_x.front(), cell_x.back(), options_.ini_th_fast);
    for (std::size_t j = 0; j + 1 < cell_x.size(); ++j) {
      const int x0 = cell_x[j], x1 = cell_x[j + 1];
      if (take_corners(y0, y1, x0, x1, min_x, min_y)) continue;
      // No corner at ini_th_fast (so none of the cell's bits is set): the
      // cell's own area again at min_th_fast.
      rescore(cv::Rect(x0, y0, x1 - x0, y1 - y0));
      band_maxima(cells, y0, y1, x0, x1, options_.min_th_fast);
      take_corners(y0, y1, x0, x1, min_x, min_y);
    }
  }
}

void OrbExtractor::band_maxima(const LevelCells& cells, int y_begin, int y_end, int x_begin, int x_end, int threshold) {
  const auto stride = static_cast<std::size_t>(scores_stride_);
  for (int y = y_begin; y < y_end; ++y) {
    const std::uint8_t* row = scores_.data() + static_cast<std::size_t>(y) * stride;
    const std::uint8_t* up = y == y_begin ? zero_row_.data() : row - stride;
    const std::uint8_t* down = y + 1 == y_end ? zero_row_.data() : row + stride;
    maxima_row(up, row, down, cells.left_in_cell.data(), cells.right_in_cell.data(), x_begin, x_end, threshold,
               band_bits_.data() + static_cast<std::size_t>(y - y_begin) * band_words_, options_.use_avx2);
  }
}

bool OrbExtractor::take_corners(int y_begin, int y_end, int x_begin, int x_end, int min_x, int min_y) {
  const std::size_t before = candidates_.size();
  const auto stride = static_cast<std::size_t>(scores_stride_);
  const int first_word = x_begin >> 6, last_word = (x_end - 1) >> 6;
  const std::uint64_t first_mask = ~std::uint64_t{0} << (x_begin & 63);
  const std::uint64_t last_mask = (x_end & 63) == 0 ? ~std::uint64_t{0} : (std::uint64_t{1} << (x_end & 63)) - 1;
  for (int y = y_begin; y < y_end; ++y) {
    const std::uint64_t* bits = band_bits_.data() + static_cast<std::size_t>(y - y_begin) * band_words_;
    const std::uint8_t* scores = scores_.data() + static_cast<std::size_t>(y) * stride;
    for (int k = first_word; k <= last_word; ++k) {
      std::uint64_t word = bits[k];
      if (k == first_word) word &= first_mask;
      if (k == last_word) word &= last_mask;
      while (word != 0) {
        const int x = (k << 6) + std::countr_zero(word);
        word &= word - 1;
        const auto index = static_cast<std::uint32_t>(candidates_.size());  // < 2^24 (detect_level)
        candidates_.push_back({static_cast<std::uint16_t>(x - min_x), static_cast<std::uint16_t>(y - min_y),
                               (static_cast<std::uint32_t>(scores[x]) << 24) | ((1u << 24) - 1 - index)});
      }
    }
  }
  return candidates_.size() > before;
}

std::vector<cv::KeyPoint> OrbExtractor::fast_corners(int level) {
  ORBATLAS_CHECK(level >= 0 && level < static_cast<int>(pyramid_.size()) && !pyramid_[0].empty(),
                 "ORB: no level " << level << " (extract an image first)");
  detect_level(level);
  std::vector<cv::KeyPoint> out;
  out.reserve(candidates_.size());
  const float offset = static_cast<float>(kBorder - kFastRadius);
  for (const Candidate& c : candidates_)
    out.emplace_back(static_cast<float>(c.x) + offset, static_cast<float>(c.y) + offset, 7.0f, -1.0f,
                     static_cast<float>(c.response()));
  return out;
}

void OrbExtractor::split(std::uint32_t node_index) {
  const QuadNode parent = nodes_[node_index];
  nodes_[node_index].alive = false;
  --alive_nodes_;
  const int half_x = (parent.x1 - parent.x0 + 1) / 2, half_y = (parent.y1 - parent.y0 + 1) / 2;
  const int mid_x = parent.x0 + half_x, mid_y = parent.y0 + half_y;
  // The node's candidates into the four quadrants, without a branch on each
  // candidate's side (std::partition mispredicted about half of them): one
  // pass counts the quadrants, a second scatters into scratch, which is copied
  // back. The order inside a child does not matter: it keeps its strongest.
  Candidate* const first = order_.data() + parent.begin;
  const std::uint32_t n = parent.end - parent.begin;
  std::uint32_t bottom = 0, right = 0, bottom_right = 0;
  for (std::uint32_t i = 0; i < n; ++i) {
    const std::uint32_t b = first[i].y >= mid_y, r = first[i].x >= mid_x;
    bottom += b;
    right += r;
    bottom_right += b & r;
  }
  const std::uint32_t top_right = right - bottom_right, bottom_left = bottom - bottom_right;
  const std::uint32_t top_left = n - top_right - bottom_left - bottom_right;
  std::uint32_t at[4] = {0, top_left, top_left + top_right, top_left + top_right + bottom_left};
  if (split_scratch_.size() < n) split_scratch_.resize(n);
  for (std::uint32_t i = 0; i < n; ++i) {
    const unsigned quadrant =
        (static_cast<unsigned>(first[i].y >= mid_y) << 1) | static_cast<unsigned>(first[i].x >= mid_x);
    split_scratch_[at[quadrant]++] = first[i];
  }
  std::copy_n(split_scratch_.begin(), n, first);
  const std::uint32_t b0 = parent.begin, b1 = b0 + top_left, b2 = b1 + top_right, b3 = b2 + bottom_left;
  const QuadNode children[4] = {
      {parent.x0, parent.y0, mid_x, mid_y, b0, b1, true},
      {mid_x, parent.y0, parent.x1, mid_y, b1, b2, true},
      {parent.x0, mid_y, mid_x, parent.y1, b2, b3, true},
      {mid_x, mid_y, parent.x1, parent.y1, b3, parent.end, true},
  };
  for (const QuadNode& child : children) {
    const std::uint32_t count = child.end - child.begin;
    if (count == 0) continue;
    nodes_.push_back(child);
    ++alive_nodes_;
    if (count > 1) to_expand_.emplace_back(count, static_cast<std::uint32_t>(nodes_.size() - 1));
  }
}

void OrbExtractor::distribute(int width, int height, int target) {
  selected_.clear();
  const auto n = static_cast<std::uint32_t>(candidates_.size());
  if (n == 0 || target <= 0) return;
  order_.resize(n);
  nodes_.clear();
  to_expand_.clear();
  alive_nodes_ = 0;

  // Initial nodes: about square, side by side along the longer axis.
  const int n_initial = std::max(1, static_cast<int>(std::lround(static_cast<double>(width) / std::max(1, height))));
  const double node_w = static_cast<double>(width) / n_initial;
  // Counting sort of the candidates into the initial nodes (stable: detection order).
  const auto initial_of = [&](std::uint32_t c) {
    return std::min(n_initial - 1, static_cast<int>(static_cast<double>(candidates_[c].x) / node_w));
  };
  // (The candidates themselves, not indices: the partitions below read them in place.)
  initial_begin_.assign(static_cast<std::size_t>(n_initial) + 1, 0);
  for (std::uint32_t c = 0; c < n; ++c) ++initial_begin_[static_cast<std::size_t>(initial_of(c)) + 1];
  for (std::size_t i = 1; i < initial_begin_.size(); ++i) initial_begin_[i] += initial_begin_[i - 1];
  for (std::uint32_t c = 0; c < n; ++c)
    order_[initial_begin_[static_cast<std::size_t>(initial_of(c))]++] = candidates_[c];
  // Each slot now holds the end of its node, which is where the next one begins.
  for (int i = 0; i < n_initial; ++i) {
    const std::uint32_t begin = i == 0 ? 0 : initial_begin_[static_cast<std::size_t>(i) - 1];
    const std::uint32_t end = initial_begin_[static_cast<std::size_t>(i)];
    if (end > begin) {
      nodes_.push_back({static_cast<int>(node_w * i), 0, static_cast<int>(node_w * (i + 1)), height, begin, end, true});
      ++alive_nodes_;
    }
  }

  const auto target_n = static_cast<std::uint32_t>(target);
  bool finished = false;
  while (!finished) {
    // A full pass: every node holding more than one candidate splits in four.
    const std::uint32_t before = alive_nodes_;
    to_expand_.clear();
    const auto existing = static_cast<std::uint32_t>(nodes_.size());
    for (std::uint32_t i = 0; i < existing; ++i)
      if (nodes_[i].alive && nodes_[i].end - nodes_[i].begin > 1) split(i);
    if (alive_nodes_ >= target_n || alive_nodes_ == before) break;
    if (alive_nodes_ + 3 * to_expand_.size() <= target_n) continue;
    // The next full pass could overshoot: split the most populated nodes first
    // and stop as soon as the target is reached (ORB-SLAM's DistributeOctTree).
    while (!finished) {
      const std::uint32_t before_pass = alive_nodes_;
      expanding_.swap(to_expand_);
      to_expand_.clear();
      std::sort(expanding_.begin(), expanding_.end());
      for (auto it = expanding_.rbegin(); it != expanding_.rend(); ++it) {
        split(it->second);
        if (alive_nodes_ >= target_n) break;
      }
      finished = alive_nodes_ >= target_n || alive_nodes_ == before_pass;
    }
  }

  // The strongest corner of each node (ties: the first detected): the largest key.
  for (const QuadNode& node : nodes_) {
    if (!node.alive) continue;
    const Candidate* best = &order_[node.begin];
    for (std::uint32_t k = node.begin + 1; k < node.end; ++k)
      if (order_[k].key > best->key) best = &order_[k];
    selected_.push_back(*best);
  }
}

ImageFeatures OrbExtractor::extract(const cv::Mat& image) {
  ORBATLAS_CHECK(!image.empty() && image.type() == CV_8UC1, "ORB: the image must be a non-empty CV_8UC1 image, got "
                                                                << image.cols << "x" << image.rows << " of type "
                                                                << image.type());
  build_pyramid(image);
  ImageFeatures out;
  out.width = image.cols;
  out.height = image.rows;
  out.keypoints.reserve(static_cast<std::size_t>(options_.n_features) + 4 * pyramid_.size());
  out.descriptors.reserve(out.keypoints.capacity());

  for (std::size_t level = 0; level < pyramid_.size(); ++level) {
    const cv::Mat& img = pyramid_[level];
    detect_level(static_cast<int>(level));
    const int min_x = kBorder - kFastRadius, min_y = kBorder - kFastRadius;
    distribute(img.cols - kBorder + kFastRadius - min_x, img.rows - kBorder + kFastRadius - min_y,
               features_per_level_[level]);
    if (selected_.empty()) continue;

    const Eigen::Vector2f ratio = level_ratios_[level];
    // Rotated BRIEF on the blurred level (cv::ORB's bits with opencv_blur).
    // (One buffer for every level, a view of its corner: the levels are blurred
    // one after another, and what was blurred last is still in the cache.)
    cv::Mat blurred = blur_buffer_(cv::Rect(0, 0, img.cols, img.rows));
    if (options_.opencv_blur)
      RotatedBrief::blur_as_opencv(img, blurred);
    else
      RotatedBrief::blur(img, blurred, options_.use_avx2);
    for (const Candidate& cand : selected_) {
      const int x = static_cast<int>(cand.x) + min_x, y = static_cast<int>(cand.y) + min_y;
      const float angle = centroid_.angle(img, x, y, options_.use_avx2);
      Keypoint kp;
      kp.uv = Eigen::Vector2f(full_image_coordinate(static_cast<float>(x), ratio.x()),
                              full_image_coordinate(static_cast<float>(y), ratio.y()));
      kp.level = static_cast<int>(level);
      kp.angle_deg = angle;
      kp.response = static_cast<float>(cand.response());
      out.keypoints.push_back(kp);
      out.descriptors.push_back(brief_.describe(blurred, x, y, angle, options_.use_avx2));
    }
  }
  return out;
}

}  // namespace orbatlas
