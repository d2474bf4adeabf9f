#pragma once
// cv::resize(src, dst, size, 0, 0, cv::INTER_LINEAR) for 8-bit grey images, bit
// for bit, with its tables made once per pair of sizes (the ORB pyramid resizes
// between the same sizes every frame). OpenCV's fixed-point scheme: 11-bit
// horizontal weights into 32-bit sums, then rows blended with 11-bit weights by
// the arithmetic of OpenCV 4.6's SIMD path (16-bit high products, rounded by
// 2 bits; it differs from rounding the exact sum), so the pyramid, the features
// and the trajectories do not change. An AVX2 path serves the horizontal pass
// with byte shuffles; the tests compare both paths with cv::resize. A profile had the
// pyramid's cv::resize chain at about 0.5 ms of every image.
#include <cstdint>
#include <vector>

#include <opencv2/core/mat.hpp>

namespace orbatlas {

class LinearResize {
 public:
  LinearResize() = default;
  LinearResize(cv::Size from, cv::Size to);

  cv::Size from() const { return from_; }
  cv::Size to() const { return to_; }

  // `src` must be CV_8UC1 of from(); `dst` is (re)allocated to to() unless it
  // already has that size and type (a view into a larger buffer stays one).
  // Throws Error otherwise.
  void operator()(const cv::Mat& src, cv::Mat& dst, bool use_avx2 = true);

 private:
  void horizontal(const std::uint8_t* row, std::int32_t* out, bool avx2) const;
  void vertical(const std::int32_t* row0, const std::int32_t* row1, std::int16_t b0, std::int16_t b1, std::uint8_t* out,
                bool avx2) const;

  cv::Size from_, to_;
  std::vector<int> xofs_;            // source column of each output column's first tap
  std::vector<std::int16_t> alpha_;  // two horizontal weights per output column
  std::vector<int> yofs_;            // source row of each output row's first tap (unclamped)
  std::vector<std::int16_t> beta_;   // two vertical weights per output row
  // The AVX2 horizontal pass: blocks of eight output columns whose two taps lie
  // in 16 bytes from block_start_; the byte each tap takes from there.
  std::vector<int> block_start_;
  std::vector<std::uint8_t> block_shuffle_;  // 16 per block
  std::vector<int> slow_blocks_;             // blocks whose taps do not fit (block_start_ -1): one by one
  std::vector<std::int32_t> rows_[2];        // the two source rows, resized horizontally
};

}  // namespace orbatlas
