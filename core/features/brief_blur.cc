#include "core/features/brief_blur.h"

#include <algorithm>
#include <array>
#include <cstdint>
#include <vector>
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define ORBATLAS_BLUR_AVX2 1
#endif

#include "core/features/cpu_features.h"

namespace orbatlas {
namespace {

constexpr int kRadius = 3;
constexpr int kRing = 8;  // rows of horizontal sums kept: the 7 a column needs, plus the next
using Rows = std::array<const std::uint16_t*, 2 * kRadius + 1>;

// Each column tap times 512, so that the high half of a 16-bit product with a
// pair of halved row sums is that tap's share in 1/256 of a grey level.
constexpr int kColumnScale = 512;
// Added before rounding, for what the truncated products and halved row sums
// lose: 1/256 leaves fewest pixels off the exact blur (0.21 % on the test's
// images; 0.55 % with 0, 0.26 % with 2).
constexpr int kColumnBias = 1;

// The horizontal pass of one pixel, halved: at most 255 * 256 / 2 = 32640, so a
// pair of them still fits 16 bits.
inline std::uint16_t half_row_sum(const std::uint8_t* p) {
  return static_cast<std::uint16_t>((kBriefBlurTaps[0] * p[0] + kBriefBlurTaps[1] * (p[-1] + p[1]) +
                                     kBriefBlurTaps[2] * (p[-2] + p[2]) + kBriefBlurTaps[3] * (p[-3] + p[3])) >>
                                    1);
}

inline std::uint32_t column_share(std::uint32_t pair, int tap) {
  return (pair * static_cast<std::uint32_t>(tap * kColumnScale)) >> 16;
}

// The vertical pass of one pixel, as the AVX2 path computes it.
inline std::uint8_t column_pixel(const Rows& rows, int x) {
  const auto at = [&](int i) { return std::uint32_t{rows[static_cast<std::size_t>(i)][x]}; };
  const std::uint32_t s = column_share(at(3), kBriefBlurTaps[0]) + column_share(at(2) + at(4), kBriefBlurTaps[1]) +
                          column_share(at(1) + at(5), kBriefBlurTaps[2]) +
                          column_share(at(0) + at(6), kBriefBlurTaps[3]);
  return static_cast<std::uint8_t>(std::min<std::uint32_t>((s + 128 + kColumnBias) >> 8, 255));
}

void row_pass_plain(const std::uint8_t* p, int from, int width, std::uint16_t* out) {
  for (int x = from; x < width; ++x) out[x] = half_row_sum(p + x);
}

void column_pass_plain(const Rows& rows, int from, int width, std::uint8_t* out) {
  for (int x = from; x < width; ++x) out[x] = column_pixel(rows, x);
}

#if defined(ORBATLAS_BLUR_AVX2)
__attribute__((target("avx2"))) inline __m256i widened_bytes(const std::uint8_t* p) {
  return _mm256_cvtepu8_epi16(_mm_loadu_si128(reinterpret_cast<const __m128i*>(p)));
}

__attribute__((target("avx2"))) inline __m256i words(const std::uint16_t* p) {
  return _mm256_loadu_si256(reinterpret_cast<const __m256i*>(p));
}

// Sixteen pixels a block; a block reads p[x - 3, x + 18], inside the row's
// 3-pixel border. The products and sums stay within 16 bits (at most 65280).
__attribute__((target("avx2"))) void row_pass_avx2(const std::uint8_t* p, int width, std::uint16_t* out) {
  const __m256i k0 = _mm256_set1_epi16(kBriefBlurTaps[0]), k1 = _mm256_set1_epi16(kBriefBlurTaps[1]);
  const __m256i k2 = _mm256_set1_epi16(kBriefBlurTaps[2]), k3 = _mm256_set1_epi16(kBriefBlurTaps[3]);
  int x = 0;
  for (; x + 16 <= width; x += 16) {
    __m256i s = _mm256_mullo_epi16(widened_bytes(p + x), k0);
    s = _mm256_add_epi16(s,
                         _mm256_mullo_epi16(_mm256_add_epi16(widened_bytes(p + x - 1), widened_bytes(p + x + 1)), k1));
    s = _mm256_add_epi16(s,
                         _mm256_mullo_epi16(_mm256_add_epi16(widened_bytes(p + x - 2), widened_bytes(p + x + 2)), k2));
    s = _mm256_add_epi16(s,
                         _mm256_mullo_epi16(_mm256_add_epi16(widened_bytes(p + x - 3), widened_bytes(p + x + 3)), k3));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(out + x), _mm256_srli_epi16(s, 1));
  }
  row_pass_plain(p, x, width, out);
}

// Sixteen pixels' weighted sums in 1/256 of a grey level.
__attribute__((target("avx2"))) inline __m256i column_sums(const Rows& r, int x) {
  __m256i s =
      _mm256_mulhi_epu16(words(r[3] + x), _mm256_set1_epi16(static_cast<short>(kBriefBlurTaps[0] * kColumnScale)));
  s = _mm256_add_epi16(s, _mm256_mulhi_epu16(_mm256_add_epi16(words(r[2] + x), words(r[4] + x)),
                                             _mm256_set1_epi16(static_cast<short>(kBriefBlurTaps[1] * kColumnScale))));
  s = _mm256_add_epi16(s, _mm256_mulhi_epu16(_mm256_add_epi16(words(r[1] + x), words(r[5] + x)),
                                             _mm256_set1_epi16(static_cast<short>(kBriefBlurTaps[2] * kColumnScale))));
  s = _mm256_add_epi16(s, _mm256_mulhi_epu16(_mm256_add_epi16(words(r[0] + x), words(r[6] + x)),
                                             _mm256_set1_epi16(static_cast<short>(kBriefBlurTaps[3] * kColumnScale))));
  return _mm256_srli_epi16(_mm256_adds_epu16(s, _mm256_set1_epi16(128 + kColumnBias)), 8);
}

__attribute__((target("avx2"))) void column_pass_avx2(const Rows& rows, int width, std::uint8_t* out) {
  int x = 0;
  for (; x + 32 <= width; x += 32) {
    const __m256i bytes = _mm256_packus_epi16(column_sums(rows, x), column_sums(rows, x + 16));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(out + x), _mm256_permute4x64_epi64(bytes, 0xd8));
  }
  for (; x + 16 <= width; x += 16) {
    const __m256i sums = column_sums(rows, x);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out + x),
                     _mm_packus_epi16(_mm256_castsi256_si128(sums), _mm256_extracti128_si256(sums, 1)));
  }
  column_pass_plain(rows, x, width, out);
}
#endif

}  // namespace

void brief_blur(const cv::Mat& view, cv::Mat& dst, bool use_avx2) {
  const int width = view.cols, height = view.rows;
  dst.create(view.size(), CV_8UC1);
  const bool avx2 = use_avx2 && cpu_has_avx2();  // false wherever ORBATLAS_BLUR_AVX2 is not defined
  const auto stride = static_cast<std::size_t>(width + 16);
  std::vector<std::uint16_t> ring(kRing * stride);
  const auto slot = [&](int r) { return ring.data() + static_cast<std::size_t>((r + kRing) % kRing) * stride; };
  const auto row_pass = [&](int r) {
    const std::uint8_t* p = view.ptr<std::uint8_t>(0) + static_cast<std::ptrdiff_t>(r) * view.step[0];
#if defined(ORBATLAS_BLUR_AVX2)
    if (avx2) return row_pass_avx2(p, width, slot(r));
#endif
    row_pass_plain(p, 0, width, slot(r));
  };
  for (int r = -kRadius; r < kRadius; ++r) row_pass(r);
  Rows rows{};
  for (int y = 0; y < height; ++y) {
    row_pass(y + kRadius);
    for (int i = 0; i < 2 * kRadius + 1; ++i) rows[static_cast<std::size_t>(i)] = slot(y - kRadius + i);
    std::uint8_t* out = dst.ptr<std::uint8_t>(y);
#if defined(ORBATLAS_BLUR_AVX2)
    if (avx2) {
      column_pass_avx2(rows, width, out);
      continue;
    }
#endif
    column_pass_plain(rows, 0, width, out);
  }
}

}  // namespace orbatlas
