#include "core/features/linear_resize.h"

#include <emmintrin.h>
#include <immintrin.h>

#include <algorithm>
#include <cmath>
#include <opencv2/core.hpp>

#include "core/common/error.h"
#include "core/features/cpu_features.h"

namespace orbatlas {

namespace {

constexpr int kCoefBits = 11;  // cv::INTER_RESIZE_COEF_BITS
constexpr int kCoefScale = 1 << kCoefBits;
constexpr int kBlock = 8;  // output columns per shuffled block

// OpenCV's saturate_cast<short>(float): rounded to nearest, ties to even.
std::int16_t weight(float w) {
  const long v = std::lrint(w * static_cast<float>(kCoefScale));
  return static_cast<std::int16_t>(std::clamp(v, -32768L, 32767L));
}

// OpenCV's source coordinate of output index d for a scale of src/dst, in
// float as it computes it: the whole part and the fraction.
void source_position(int d, double scale, int* s, float* f) {
  const float x = static_cast<float>((d + 0.5) * scale - 0.5);
  *s = static_cast<int>(std::floor(x));
  *f = x - static_cast<float>(*s);
}

std::uint8_t saturate_u8(int v) { return static_cast<std::uint8_t>(std::clamp(v, 0, 255)); }
std::int16_t saturate_s16(int v) { return static_cast<std::int16_t>(std::clamp(v, -32768, 32767)); }

// OpenCV's VResizeLinearVec_32s8u, one column: both sums shifted to 16 bits,
// high halves of the products, a saturating add, then (v + 2) >> 2. OpenCV
// 4.6's results match this in every column, the last ones of a row too (the
// tests: its scalar FixedPtCast, which rounds the exact sum, would differ).
std::uint8_t blend_simd(std::int32_t s0, std::int32_t s1, std::int16_t b0, std::int16_t b1) {
  const int m0 = (saturate_s16(s0 >> 4) * b0) >> 16, m1 = (saturate_s16(s1 >> 4) * b1) >> 16;
  return saturate_u8(saturate_s16(saturate_s16(m0 + m1) + 2) >> 2);
}

__attribute__((target("avx2"))) void horizontal_blocks_avx2(const std::uint8_t* row, std::int32_t* out,
                                                            const int* block_start, const std::uint8_t* shuffle,
                                                            const std::int16_t* alpha, int blocks) {
  for (int b = 0; b < blocks; ++b) {
    if (block_start[b] < 0) continue;
    const __m128i src = _mm_loadu_si128(reinterpret_cast<const __m128i*>(row + block_start[b]));
    const __m128i pairs =
        _mm_shuffle_epi8(src, _mm_loadu_si128(reinterpret_cast<const __m128i*>(shuffle + kBlock * 2 * b)));
    const __m256i wide = _mm256_cvtepu8_epi16(pairs);
    const __m256i weights = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(alpha + kBlock * 2 * b));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(out + kBlock * b), _mm256_madd_epi16(wide, weights));
  }
}

__attribute__((target("avx2"))) inline __m256i load8(const std::int32_t* p) {
  return _mm256_loadu_si256(reinterpret_cast<const __m256i*>(p));
}

// Sixteen columns of the blend at a time; returns the first column not done.
__attribute__((target("avx2"))) int vertical_avx2(const std::int32_t* row0, const std::int32_t* row1, std::int16_t b0,
                                                  std::int16_t b1, std::uint8_t* out, int width) {
  const __m256i w0 = _mm256_set1_epi16(b0), w1 = _mm256_set1_epi16(b1), two = _mm256_set1_epi16(2);
  int x = 0;
  for (; x + 16 <= width; x += 16) {
    // packs interleaves the lanes (columns 0-3, 8-11 | 4-7, 12-15); the blend is per column.
    const __m256i s0 =
        _mm256_packs_epi32(_mm256_srai_epi32(load8(row0 + x), 4), _mm256_srai_epi32(load8(row0 + x + 8), 4));
    const __m256i s1 =
        _mm256_packs_epi32(_mm256_srai_epi32(load8(row1 + x), 4), _mm256_srai_epi32(load8(row1 + x + 8), 4));
    const __m256i sum = _mm256_adds_epi16(_mm256_mulhi_epi16(s0, w0), _mm256_mulhi_epi16(s1, w1));
    const __m256i v = _mm256_permute4x64_epi64(_mm256_srai_epi16(_mm256_adds_epi16(sum, two), 2), 0xD8);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out + x),
                     _mm_packus_epi16(_mm256_castsi256_si128(v), _mm256_extracti128_si256(v, 1)));
  }
  return x;
}

}  // namespace

LinearResize::LinearResize(cv::Size from, cv::Size to) : from_(from), to_(to) {
  ORBATLAS_CHECK(from.width >= 1 && from.height >= 1 && to.width >= 1 && to.height >= 1,
                 "resize: sizes must be positive, not " << from << " -> " << to);
  // As cv::resize: the inverse scales from the sizes, then their inverses.
  const double scale_x = 1.0 / (static_cast<double>(to.width) / from.width);
  const double scale_y = 1.0 / (static_cast<double>(to.height) / from.height);
  xofs_.resize(2 * static_cast<std::size_t>(to.width));
  alpha_.resize(2 * static_cast<std::size_t>(to.width));
  for (int dx = 0; dx < to.width; ++dx) {
    int sx = 0;
    float fx = 0.f;
    source_position(dx, scale_x, &sx, &fx);
    if (sx < 0) fx = 0.f, sx = 0;
    int second = sx + 1;
    if (second >= from.width) {
      // OpenCV takes the last column alone (times 2048); its second tap here is
      // the same column with weight 0, so that no tap leaves the row.
      fx = 0.f, sx = from.width - 1;
      second = sx;
    }
    xofs_[2 * dx] = sx;
    xofs_[2 * dx + 1] = second;
    alpha_[2 * dx] = weight(1.f - fx);
    alpha_[2 * dx + 1] = weight(fx);
  }
  yofs_.resize(static_cast<std::size_t>(to.height));
  beta_.resize(2 * static_cast<std::size_t>(to.height));
  for (int dy = 0; dy < to.height; ++dy) {
    float fy = 0.f;
    source_position(dy, scale_y, &yofs_[dy], &fy);
    beta_[2 * dy] = weight(1.f - fy);
    beta_[2 * dy + 1] = weight(fy);
  }
  const int blocks = to.width / kBlock;
  block_start_.assign(static_cast<std::size_t>(blocks), -1);
  block_shuffle_.assign(static_cast<std::size_t>(blocks) * 2 * kBlock, 0);
  for (int b = 0; b < blocks; ++b) {
    const int start = xofs_[2 * kBlock * b];
    bool fits = start + 16 <= from.width;
    for (int k = 0; k < 2 * kBlock && fits; ++k) {
      const int offset = xofs_[2 * kBlock * b + k] - start;
      fits = offset >= 0 && offset < 16;
      if (fits) block_shuffle_[2 * kBlock * b + k] = static_cast<std::uint8_t>(offset);
    }
    if (fits)
      block_start_[b] = start;
    else
      slow_blocks_.push_back(b);
  }
  rows_[0].resize(static_cast<std::size_t>(to.width));
  rows_[1].resize(static_cast<std::size_t>(to.width));
}

void LinearResize::horizontal(const std::uint8_t* row, std::int32_t* out, bool avx2) const {
  const auto one_by_one = [&](int from, int to) {
    for (int dx = from; dx < to; ++dx)
      out[dx] = row[xofs_[2 * dx]] * alpha_[2 * dx] + row[xofs_[2 * dx + 1]] * alpha_[2 * dx + 1];
  };
  const int blocks = static_cast<int>(block_start_.size());
  if (avx2) {
    horizontal_blocks_avx2(row, out, block_start_.data(), block_shuffle_.data(), alpha_.data(), blocks);
    for (const int b : slow_blocks_) one_by_one(kBlock * b, kBlock * (b + 1));
    one_by_one(kBlock * blocks, to_.width);
  } else {
    one_by_one(0, to_.width);
  }
}

void LinearResize::vertical(const std::int32_t* row0, const std::int32_t* row1, std::int16_t b0, std::int16_t b1,
                            std::uint8_t* out, bool avx2) const {
  // Eight columns at a time with SSE2 (baseline x86-64), the rest one by one.
  const __m128i w0 = _mm_set1_epi16(b0), w1 = _mm_set1_epi16(b1), two = _mm_set1_epi16(2);
  int x = avx2 ? vertical_avx2(row0, row1, b0, b1, out, to_.width) : 0;
  for (; x + 8 <= to_.width; x += 8) {
    const auto load = [](const std::int32_t* p) { return _mm_loadu_si128(reinterpret_cast<const __m128i*>(p)); };
    const __m128i s0 = _mm_packs_epi32(_mm_srai_epi32(load(row0 + x), 4), _mm_srai_epi32(load(row0 + x + 4), 4));
    const __m128i s1 = _mm_packs_epi32(_mm_srai_epi32(load(row1 + x), 4), _mm_srai_epi32(load(row1 + x + 4), 4));
    const __m128i sum = _mm_adds_epi16(_mm_mulhi_epi16(s0, w0), _mm_mulhi_epi16(s1, w1));
    const __m128i v = _mm_srai_epi16(_mm_adds_epi16(sum, two), 2);
    _mm_storel_epi64(reinterpret_cast<__m128i*>(out + x), _mm_packus_epi16(v, v));
  }
  for (; x < to_.width; ++x) out[x] = blend_simd(row0[x], row1[x], b0, b1);
}

void LinearResize::operator()(const cv::Mat& src, cv::Mat& dst, bool use_avx2) {
  ORBATLAS_CHECK(src.type() == CV_8UC1, "resize: an 8-bit grey image is needed, not type " << src.type());
  ORBATLAS_CHECK(src.size() == from_, "resize: made for " << from_ << ", given " << src.size());
  if (dst.size() != to_ || dst.type() != CV_8UC1) dst.create(to_, CV_8UC1);
  ORBATLAS_CHECK(dst.data != src.data, "resize: the output cannot be the input");
  const bool avx2 = use_avx2 && cpu_has_avx2();
  int cached[2] = {-1, -1};  // the source row each of rows_ holds
  for (int dy = 0; dy < to_.height; ++dy) {
    const int sy0 = std::clamp(yofs_[dy], 0, from_.height - 1), sy1 = std::clamp(yofs_[dy] + 1, 0, from_.height - 1);
    // The row wanted first may be in either buffer (the next output row usually
    // starts where this one's second row was).
    if (cached[0] != sy0 && cached[1] == sy0) {
      std::swap(rows_[0], rows_[1]);
      std::swap(cached[0], cached[1]);
    }
    if (cached[0] != sy0) {
      horizontal(src.ptr<std::uint8_t>(sy0), rows_[0].data(), avx2);
      cached[0] = sy0;
    }
    if (cached[1] != sy1) {
      if (sy1 == sy0) {
        rows_[1] = rows_[0];
      } else {
        horizontal(src.ptr<std::uint8_t>(sy1), rows_[1].data(), avx2);
      }
      cached[1] = sy1;
    }
    vertical(rows_[0].data(), rows_[1].data(), beta_[2 * dy], beta_[2 * dy + 1], dst.ptr<std::uint8_t>(dy), avx2);
  }
}

}  // namespace orbatlas
