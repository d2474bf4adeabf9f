#pragma once
// ORB features the ORB-SLAM way: a scale pyramid, FAST per grid cell with a
// high threshold and a low fallback, a quadtree that spreads the keypoints over
// the image down to the requested count, orientation by intensity centroid and
// 256-bit rotated BRIEF. All of it is ours, bit for bit what ORB-SLAM gets from
// OpenCV: the pyramid's resize (linear_resize.h), FAST (fast_kernels.h: a SIMD
// score map giving exactly cv::FAST's corners per cell), the distribution, the
// orientation and the BRIEF tests (OpenCV's bits, eight at a time); only the
// descriptors' blur is a faster one unless opencv_blur asks for cv::GaussianBlur's.
// One extractor per thread (scratch buffers).
#include <cstdint>
#include <opencv2/core/mat.hpp>
#include <utility>
#include <vector>

#include "core/features/intensity_centroid.h"
#include "core/features/keypoint.h"
#include "core/features/linear_resize.h"
#include "core/features/rotated_brief.h"

namespace orbatlas {

struct OrbExtractorOptions {
  int n_features = 1200;
  double scale_factor = 1.2;
  int n_levels = 8;
  int ini_th_fast = 20;
  int min_th_fast = 7;
  int cell_size = 35;  // FAST grid cell, pixels
  // FAST scores 32 pixels at a time, orientation a row of the patch at a time
  // and BRIEF tests 8 at a time where the CPU has AVX2 (else FAST 16 at a
  // time, SSE2, the rest one pixel at a time): the same features; false forces
  // the narrower paths (tests compare the two).
  bool use_avx2 = true;
  // The descriptors' blur: false (default) our fixed-point one, about twice as
  // fast; true cv::GaussianBlur as cv::ORB runs it, for descriptors equal to
  // cv::ORB's bit for bit (tests; RotatedBrief::blur_as_opencv).
  bool opencv_blur = false;
  void check() const;  // throws Error on invalid values
};

class OrbExtractor {
 public:
  // Each pyramid() level is a view into a buffer with this many valid pixels on
  // every side (BORDER_REFLECT_101), as ORB-SLAM's EDGE_THRESHOLD. Keypoints lie
  // at least this far from the level image's edges.
  static constexpr int kPyramidBorder = 19;

  explicit OrbExtractor(const OrbExtractorOptions& options);
  // Not copyable: a copy would share the pyramid buffers (cv::Mat is shallow).
  OrbExtractor(const OrbExtractor&) = delete;
  OrbExtractor& operator=(const OrbExtractor&) = delete;
  OrbExtractor(OrbExtractor&&) = default;
  OrbExtractor& operator=(OrbExtractor&&) = default;

  // image: CV_8UC1. Fills keypoints (uv, level, angle, response) and descriptors;
  // bearing / uv_undistorted are left for the camera model.
  ImageFeatures extract(const cv::Mat& image);

  const OrbExtractorOptions& options() const { return options_; }
  // Scale of each level (1, 1.2, 1.44, ...) and the squared sigma of a keypoint's
  // position error at that level (scale^2), used by optimisers.
  const std::vector<double>& scale_factors() const { return scale_factors_; }
  const std::vector<double>& level_sigma2() const { return level_sigma2_; }
  const std::vector<cv::Mat>& pyramid() const { return pyramid_; }  // of the last image
  // The full image's size over each level's, per axis (x, y), of the last image:
  // its scale factor up to the rounding of the level's size. A level's pixel
  // (x, y) is at full_image_coordinate(x, ratio.x), (y, ratio.y) in the image
  // (keypoint.h), where its keypoint is placed.
  const std::vector<Eigen::Vector2f>& level_ratios() const { return level_ratios_; }
  // Keypoints asked of each level (geometric in the level area; they sum to n_features).
  const std::vector<int>& features_per_level() const { return features_per_level_; }

  // The FAST stage alone on level `level` of the last image: the corners (level
  // pixels, response = FAST score) before the quadtree, exactly those of
  // cv::FAST(window, ini_th_fast, nonmax) per cell window, min_th_fast where that
  // finds nothing. For tests and tools; throws Error before the first extract().
  std::vector<cv::KeyPoint> fast_corners(int level);

  // The FAST cells of one level: detection areas of columns [x_edges[j],
  // x_edges[j + 1]) and rows [y_edges[i], y_edges[i + 1]), and per column 0xff
  // where the pixel left (right) of it lies in the same cell, else 0.
  struct LevelCells {
    std::vector<int> x_edges, y_edges;
    std::vector<std::uint8_t> left_in_cell, right_in_cell;
  };

 private:
  // A FAST corner of one level, relative to the corner of the level's
  // detection area, packed for the quadtree's partitions: key is the response
  // (the FAST score) above 24 bits of 2^24 - 1 minus the detection index, so
  // the largest key is the strongest corner, ties going to the first detected.
  struct Candidate {
    std::uint16_t x, y;
    std::uint32_t key;
    std::uint8_t response() const { return static_cast<std::uint8_t>(key >> 24); }
  };
  // A quadtree node (ORB-SLAM's ExtractorNode): a rectangle [x0, x1) x [y0, y1)
  // and its candidates order_[begin, end).
  struct QuadNode {
    int x0, y0, x1, y1;
    std::uint32_t begin, end;
    bool alive;
  };

  void build_pyramid(const cv::Mat& image);
  void detect_level(int level);  // FAST per cell -> candidates_
  // The corners of one row band of cells at `threshold` into band_bits_ (bit x
  // of row r: pixel x of the band's row r), for x in [x_begin, x_end).
  void band_maxima(const LevelCells& cells, int y_begin, int y_end, int x_begin, int x_end, int threshold);
  // Appends the corners band_bits_ holds in [x_begin, x_end) of the band's rows;
  // false if there are none.
  bool take_corners(int y_begin, int y_end, int x_begin, int x_end, int min_x, int min_y);
  // Quadtree over candidates_ in a width x height area, down to `target` nodes -> selected_.
  void distribute(int width, int height, int target);
  void split(std::uint32_t node);  // children with candidates replace the node

  OrbExtractorOptions options_;
  std::vector<double> scale_factors_, level_sigma2_;
  std::vector<int> features_per_level_;
  std::vector<cv::Mat> pyramid_;
  // Scratch kept between calls so that extraction does not allocate.
  std::vector<cv::Mat> bordered_;     // level buffers; pyramid_[l] views their interior
  std::vector<LinearResize> shrink_;  // level l - 1 to level l (cv::resize's result), [0] unused
  cv::Size pyramid_size_;
  std::vector<Eigen::Vector2f> level_ratios_;  // per level, for pyramid_size_
  IntensityCentroid centroid_;                 // orientation
  RotatedBrief brief_{opencv_brief_pattern()};
  cv::Mat blur_buffer_;                   // a level blurred for the BRIEF tests (level 0's size)
  std::vector<std::uint8_t> scores_;      // FAST scores of a level
  std::size_t scores_stride_ = 0;         // its row stride (the level's width)
  std::vector<LevelCells> cells_;         // per level, for pyramid_size_
  std::vector<std::uint8_t> zero_row_;    // a row of zeros (the rows above and below a band)
  std::vector<std::uint64_t> band_bits_;  // the corners of one band of cells, a bit per pixel
  std::size_t band_words_ = 0;            // 64-bit words per row of band_bits_
  std::vector<Candidate> candidates_, order_, selected_, split_scratch_;
  std::vector<std::uint32_t> initial_begin_;
  std::vector<QuadNode> nodes_;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> to_expand_, expanding_;  // (candidate count, node)
  std::uint32_t alive_nodes_ = 0;
};

}  // namespace orbatlas
