#include "core/features/patch_sad.h"

#include <algorithm>

#include "core/features/cpu_features.h"

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define ORBATLAS_SAD_AVX2 1
#endif

namespace orbatlas {
namespace {

// The row sums below, 16 offsets at once: sad[j] += |la - rb[j] - d[j]| for j
// in [0, 16), every operand 32-bit as in the portable loop (the same values).
// `scaled` rows are `stride` ints long with at least 16 readable past each
// patch column; `d` and `sad` hold 16 ints.
#if defined(ORBATLAS_SAD_AVX2)
__attribute__((target("avx2"))) void accumulate_rows_avx2(const cv::Mat& a, int ua, int va, int w, const int* scaled,
                                                          std::size_t stride, const int* d, int n, int* sad) {
  const __m256i d0 = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(d));
  const __m256i d1 = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(d + 8));
  __m256i s0 = _mm256_setzero_si256(), s1 = _mm256_setzero_si256();
  const int side = 2 * w + 1;
  for (int dy = -w, r = 0; dy <= w; ++dy, ++r) {
    const std::uint8_t* ra = a.ptr<std::uint8_t>(va + dy) + ua - w;
    const int* row = scaled + static_cast<std::size_t>(r) * stride;
    for (int dx = 0; dx < side; ++dx) {
      const __m256i la = _mm256_set1_epi32(ra[dx] * n);
      const __m256i b0 = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(row + dx));
      const __m256i b1 = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(row + dx + 8));
      s0 = _mm256_add_epi32(s0, _mm256_abs_epi32(_mm256_sub_epi32(_mm256_sub_epi32(la, b0), d0)));
      s1 = _mm256_add_epi32(s1, _mm256_abs_epi32(_mm256_sub_epi32(_mm256_sub_epi32(la, b1), d1)));
    }
  }
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(sad), s0);
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(sad + 8), s1);
}
#endif

constexpr int kLanes = 16;  // offsets the AVX2 path computes at once

}  // namespace

void RowSadSearch::run(const cv::Mat& a, int ua, int va, const cv::Mat& b, int ub0, int range, int w,
                       std::vector<int>& out) {
  const int side = 2 * w + 1, n = side * side;
  const int offsets = 2 * range + 1, first = ub0 - range - w, columns = offsets + side - 1;
  // The right rows times n, and their column sums, over every column any
  // offset's patch reads; each row has kLanes more for the 16-wide path to read
  // (whatever they hold only reaches the lanes past `offsets`, which are dropped).
  const std::size_t stride = static_cast<std::size_t>(columns + kLanes);
  scaled_.resize(static_cast<std::size_t>(side) * stride);
  column_sums_.assign(static_cast<std::size_t>(columns), 0);
  for (int dy = -w, r = 0; dy <= w; ++dy, ++r) {
    const std::uint8_t* rb = b.ptr<std::uint8_t>(va + dy) + first;
    int* row = scaled_.data() + static_cast<std::size_t>(r) * stride;
    for (int c = 0; c < columns; ++c) {
      column_sums_[static_cast<std::size_t>(c)] += rb[c];
      row[c] = rb[c] * n;
    }
  }
  int sum_a = 0;
  for (int dy = -w; dy <= w; ++dy) {
    const std::uint8_t* ra = a.ptr<std::uint8_t>(va + dy) + ua;
    for (int dx = -w; dx <= w; ++dx) sum_a += ra[dx];
  }
  // The offset of each patch's mean difference, slid along the row.
  mean_offset_.assign(static_cast<std::size_t>(std::max(offsets, kLanes)), 0);
  int sum_b = 0;
  for (int c = 0; c < side; ++c) sum_b += column_sums_[static_cast<std::size_t>(c)];
  for (int j = 0; j < offsets; ++j) {
    if (j > 0)
      sum_b += column_sums_[static_cast<std::size_t>(j + side - 1)] - column_sums_[static_cast<std::size_t>(j - 1)];
    mean_offset_[static_cast<std::size_t>(j)] = sum_a - sum_b;
  }
#if defined(ORBATLAS_SAD_AVX2)
  if (use_avx2_ && offsets <= kLanes && cpu_has_avx2()) {
    int sad[kLanes];
    accumulate_rows_avx2(a, ua, va, w, scaled_.data(), stride, mean_offset_.data(), n, sad);
    out.assign(sad, sad + offsets);
    return;
  }
#endif
  // Pixel by pixel, every offset at once (a loop the compiler vectorises).
  out.assign(static_cast<std::size_t>(offsets), 0);
  int* sad = out.data();
  const int* d = mean_offset_.data();
  for (int dy = -w, r = 0; dy <= w; ++dy, ++r) {
    const std::uint8_t* ra = a.ptr<std::uint8_t>(va + dy) + ua - w;
    const int* row = scaled_.data() + static_cast<std::size_t>(r) * stride;
    for (int dx = 0; dx < side; ++dx) {
      const int la = ra[dx] * n;
      const int* rb = row + dx;
      for (int j = 0; j < offsets; ++j) sad[j] += std::abs(la - rb[j] - d[j]);
    }
  }
}

}  // namespace orbatlas
