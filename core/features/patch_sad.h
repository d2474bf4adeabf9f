#pragma once
// Patch comparison for sub-pixel stereo refinement.
#include <cstdint>
#include <cstdlib>
#include <opencv2/core/mat.hpp>
#include <vector>

namespace orbatlas {

inline bool patch_inside(const cv::Mat& img, int u, int v, int w) {
  return u - w >= 0 && v - w >= 0 && u + w < img.cols && v + w < img.rows;
}

// Zero-mean SAD between the (2w+1)^2 patch of `a` centred at (ua, va) and that of
// `b` at (ub, vb), times n = (2w+1)^2 (kept exact for sub-pixel fits): each patch is
// made relative to its own mean, so a brightness offset between the cameras does
// not count. (ORB-SLAM subtracts the centre pixel instead, which carries that one
// pixel's noise into every term; the mean halves the depth error on our tests.)
// Both patches must lie inside their images.
inline int zero_mean_sad(const cv::Mat& a, int ua, int va, const cv::Mat& b, int ub, int vb, int w) {
  const int side = 2 * w + 1, n = side * side;
  int sum_a = 0, sum_b = 0;
  for (int dy = -w; dy <= w; ++dy) {
    const std::uint8_t* ra = a.ptr<std::uint8_t>(va + dy) + ua;
    const std::uint8_t* rb = b.ptr<std::uint8_t>(vb + dy) + ub;
    for (int dx = -w; dx <= w; ++dx) {
      sum_a += ra[dx];
      sum_b += rb[dx];
    }
  }
  int sad = 0;
  for (int dy = -w; dy <= w; ++dy) {
    const std::uint8_t* ra = a.ptr<std::uint8_t>(va + dy) + ua;
    const std::uint8_t* rb = b.ptr<std::uint8_t>(vb + dy) + ub;
    for (int dx = -w; dx <= w; ++dx) sad += std::abs((ra[dx] - rb[dx]) * n - (sum_a - sum_b));
  }
  return sad;
}

// zero_mean_sad(a, ua, va, b, ub0 + k, va, w) for every k in -range..range,
// into out[k + range]: the same values, with the left patch and the right
// patches' sums computed once for the row (column sums slid along it) instead
// of for every offset. Every patch must lie inside its image.
class RowSadSearch {
 public:
  void run(const cv::Mat& a, int ua, int va, const cv::Mat& b, int ub0, int range, int w, std::vector<int>& out);
  // false: the portable loop even where the CPU has AVX2 (tests compare the two).
  void set_use_avx2(bool use) { use_avx2_ = use; }

 private:
  std::vector<int> scaled_, column_sums_, mean_offset_;
  bool use_avx2_ = true;
};

}  // namespace orbatlas
