// The intensity centroid, scalar and AVX2. Row v and row -v are taken together:
// m10 gains u * (below + above), m01 gains v * (below - above). With AVX2, each
// pair of rows is two 32-byte loads and four byte-times-weight multiply-adds
// (_mm256_maddubs_epi16: at most 2 * 255 * 15 per 16-bit lane, no overflow).
#include "core/features/intensity_centroid.h"

#include <cmath>
#include <opencv2/core.hpp>
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define ORBATLAS_CENTROID_AVX2 1
#endif

#include "core/features/cpu_features.h"

namespace orbatlas {
namespace {

#if defined(ORBATLAS_CENTROID_AVX2)
__attribute__((target("avx2"))) inline int horizontal_sum(__m256i v) {
  const __m128i s = _mm_add_epi32(_mm256_castsi256_si128(v), _mm256_extracti128_si256(v, 1));
  const __m128i t = _mm_add_epi32(s, _mm_shuffle_epi32(s, _MM_SHUFFLE(1, 0, 3, 2)));
  return _mm_cvtsi128_si32(_mm_add_epi32(t, _mm_shuffle_epi32(t, _MM_SHUFFLE(2, 3, 0, 1))));
}

__attribute__((target("avx2"))) inline __m256i load32(const std::uint8_t* p) {
  return _mm256_loadu_si256(reinterpret_cast<const __m256i*>(p));
}

__attribute__((target("avx2"))) inline __m256i weights32(const std::array<std::int8_t, 32>& w) {
  return _mm256_load_si256(reinterpret_cast<const __m256i*>(w.data()));
}

__attribute__((target("avx2"))) IntensityCentroid::Moments moments_avx2(
    const std::uint8_t* center, std::ptrdiff_t step, const std::array<std::array<std::int8_t, 32>, 16>& row_u,
    const std::array<std::array<std::int8_t, 32>, 16>& row_v) {
  const __m256i ones = _mm256_set1_epi16(1);
  const std::uint8_t* first = center - IntensityCentroid::kRadius;
  __m256i m10 = _mm256_madd_epi16(_mm256_maddubs_epi16(load32(first), weights32(row_u[0])), ones);
  __m256i m01 = _mm256_setzero_si256();
  for (int v = 1; v <= IntensityCentroid::kRadius; ++v) {
    const __m256i below = load32(first + v * step), above = load32(first - v * step);
    const __m256i wu = weights32(row_u[static_cast<std::size_t>(v)]),
                  wv = weights32(row_v[static_cast<std::size_t>(v)]);
    const __m256i u_sum = _mm256_add_epi16(_mm256_maddubs_epi16(below, wu), _mm256_maddubs_epi16(above, wu));
    const __m256i v_diff = _mm256_sub_epi16(_mm256_maddubs_epi16(below, wv), _mm256_maddubs_epi16(above, wv));
    m10 = _mm256_add_epi32(m10, _mm256_madd_epi16(u_sum, ones));
    m01 = _mm256_add_epi32(m01, _mm256_madd_epi16(v_diff, ones));
  }
  return {horizontal_sum(m01), horizontal_sum(m10)};
}
#endif

}  // namespace

IntensityCentroid::IntensityCentroid() {
  // Row half-widths of the circular patch, symmetric in u and v (as OpenCV's ORB).
  const int vmax = static_cast<int>(std::floor(kRadius * std::sqrt(2.0) / 2 + 1));
  const int vmin = static_cast<int>(std::ceil(kRadius * std::sqrt(2.0) / 2));
  for (int v = 0; v <= vmax; ++v)
    umax_[static_cast<std::size_t>(v)] = static_cast<int>(std::lround(std::sqrt(double(kRadius * kRadius - v * v))));
  for (int v = kRadius, v0 = 0; v >= vmin; --v) {
    while (umax_[static_cast<std::size_t>(v0)] == umax_[static_cast<std::size_t>(v0) + 1]) ++v0;
    umax_[static_cast<std::size_t>(v)] = v0;
    ++v0;
  }
  for (int v = 0; v <= kRadius; ++v)
    for (int lane = 0; lane < 32; ++lane) {
      const int u = lane - kRadius;
      const bool inside = std::abs(u) <= umax_[static_cast<std::size_t>(v)];
      row_u_[static_cast<std::size_t>(v)][static_cast<std::size_t>(lane)] = static_cast<std::int8_t>(inside ? u : 0);
      row_v_[static_cast<std::size_t>(v)][static_cast<std::size_t>(lane)] = static_cast<std::int8_t>(inside ? v : 0);
    }
}

IntensityCentroid::Moments IntensityCentroid::moments(const cv::Mat& level, int x, int y, bool use_avx2) const {
  const std::uint8_t* center = level.ptr<std::uint8_t>(y) + x;
  const auto step = static_cast<std::ptrdiff_t>(level.step1());
#if defined(ORBATLAS_CENTROID_AVX2)
  if (use_avx2 && cpu_has_avx2()) return moments_avx2(center, step, row_u_, row_v_);
#endif
  (void)use_avx2;
  Moments m;
  for (int u = -kRadius; u <= kRadius; ++u) m.m10 += u * center[u];
  for (int v = 1; v <= kRadius; ++v) {
    int v_sum = 0;
    const int d = umax_[static_cast<std::size_t>(v)];
    const std::uint8_t* below = center + v * step;
    const std::uint8_t* above = center - v * step;
    for (int u = -d; u <= d; ++u) {
      const int plus = below[u], minus = above[u];
      v_sum += plus - minus;
      m.m10 += u * (plus + minus);
    }
    m.m01 += v * v_sum;
  }
  return m;
}

float IntensityCentroid::angle(const cv::Mat& level, int x, int y, bool use_avx2) const {
  const Moments m = moments(level, x, y, use_avx2);
  const float angle = cv::fastAtan2(static_cast<float>(m.m01), static_cast<float>(m.m10));
  return angle >= 360.0f ? angle - 360.0f : angle;
}

}  // namespace orbatlas
