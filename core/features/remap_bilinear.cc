#include "core/features/remap_bilinear.h"

#include <immintrin.h>

#include <cstdint>
#include <cstring>

#include "core/common/error.h"
#include "core/features/cpu_features.h"

namespace orbatlas {

namespace {

constexpr int kTabBits = 5;  // cv::INTER_BITS: 32 steps per pixel
constexpr int kTabMask = (1 << kTabBits) - 1;

// One output pixel, any position (neighbours outside the image count as 0).
inline std::uint8_t remap_pixel(const std::uint8_t* src, std::ptrdiff_t step, int width, int height, int sx, int sy,
                                unsigned frac) {
  const int fx = static_cast<int>(frac & kTabMask), fy = static_cast<int>((frac >> kTabBits) & kTabMask);
  const int w00 = (32 - fx) * (32 - fy), w01 = fx * (32 - fy), w10 = (32 - fx) * fy, w11 = fx * fy;
  int v = 0;
  if (static_cast<unsigned>(sx) < static_cast<unsigned>(width - 1) &&
      static_cast<unsigned>(sy) < static_cast<unsigned>(height - 1)) {
    const std::uint8_t* p = src + sy * step + sx;
    v = w00 * p[0] + w01 * p[1] + w10 * p[step] + w11 * p[step + 1];
  } else {
    const auto at = [&](int x, int y) -> int {
      return x >= 0 && x < width && y >= 0 && y < height ? src[y * step + x] : 0;
    };
    v = w00 * at(sx, sy) + w01 * at(sx + 1, sy) + w10 * at(sx, sy + 1) + w11 * at(sx + 1, sy + 1);
  }
  return static_cast<std::uint8_t>((v + 512) >> 10);  // at most 1024 * 255: no saturation needed
}

void remap_row(const std::uint8_t* src, std::ptrdiff_t step, int width, int height, const std::int16_t* xy,
               const std::uint16_t* frac, std::uint8_t* dst, int from, int to) {
  for (int x = from; x < to; ++x) dst[x] = remap_pixel(src, step, width, height, xy[2 * x], xy[2 * x + 1], frac[x]);
}

// Each 32-bit lane of a gather: the pixel and its right neighbour as two 16-bit values.
__attribute__((target("avx2"))) inline __m256i pixel_pairs(__m256i gathered, __m256i byte_mask) {
  return _mm256_or_si256(_mm256_and_si256(gathered, byte_mask),
                         _mm256_slli_epi32(_mm256_and_si256(_mm256_srli_epi32(gathered, 8), byte_mask), 16));
}

// The 8 lanes' minimum, in every lane.
__attribute__((target("avx2"))) inline __m256i lanes_min(__m256i v) {
  v = _mm256_min_epi32(v, _mm256_permute2x128_si256(v, v, 1));
  v = _mm256_min_epi32(v, _mm256_shuffle_epi32(v, 0x4E));
  return _mm256_min_epi32(v, _mm256_shuffle_epi32(v, 0xB1));
}

// Eight output pixels whose sources lie in one 16-pixel window of three
// consecutive rows (a rectification map's usual block: sx within 14 of the
// least, sy the least or one more): the window's rows are loaded once and each
// pixel's neighbours picked with byte shuffles instead of gathers (slow on
// some CPUs: under load the gathers took 59 % of cv::remap's time).
// Writes the two rows' neighbour pairs for the weights; false (nothing
// written) when the block is not of that kind or reaches an edge.
__attribute__((target("avx2"))) inline bool window_pairs(const std::uint8_t* src, std::ptrdiff_t step, int width,
                                                         int height, __m256i sx, __m256i sy, __m256i* top,
                                                         __m256i* bottom) {
  const __m256i x0 = lanes_min(sx), y0 = lanes_min(sy);
  const __m256i dx = _mm256_sub_epi32(sx, x0), dy = _mm256_sub_epi32(sy, y0);
  const __m256i too_far =
      _mm256_or_si256(_mm256_cmpgt_epi32(dx, _mm256_set1_epi32(14)), _mm256_cmpgt_epi32(dy, _mm256_set1_epi32(1)));
  const int left = _mm256_cvtsi256_si32(x0), row = _mm256_cvtsi256_si32(y0);
  if (!_mm256_testz_si256(too_far, too_far) || left < 0 || row < 0 || left > width - 16 || row > height - 3)
    return false;
  const std::uint8_t* p = src + static_cast<std::ptrdiff_t>(row) * step + left;
  const __m256i r0 = _mm256_broadcastsi128_si256(_mm_loadu_si128(reinterpret_cast<const __m128i*>(p)));
  const __m256i r1 = _mm256_broadcastsi128_si256(_mm_loadu_si128(reinterpret_cast<const __m128i*>(p + step)));
  const __m256i r2 = _mm256_broadcastsi128_si256(_mm_loadu_si128(reinterpret_cast<const __m128i*>(p + 2 * step)));
  // Per 32-bit lane the bytes dx, zero, dx + 1, zero: the pixel and its right
  // neighbour as two 16-bit values (0x80 selects zero). Lane i of the low half
  // is pixel i, of the high half pixel 4 + i, as the weights are laid out.
  const __m256i index = _mm256_add_epi32(_mm256_mullo_epi32(dx, _mm256_set1_epi32(0x10001)),
                                         _mm256_set1_epi32(static_cast<int>(0x80018000u)));
  const __m256i a = _mm256_shuffle_epi8(r0, index), b = _mm256_shuffle_epi8(r1, index),
                c = _mm256_shuffle_epi8(r2, index);
  const __m256i lower = _mm256_cmpgt_epi32(dy, _mm256_setzero_si256());  // all ones where sy = y0 + 1
  *top = _mm256_blendv_epi8(a, b, lower);
  *bottom = _mm256_blendv_epi8(b, c, lower);
  return true;
}

__attribute__((target("avx2"))) void remap_row_avx2(const std::uint8_t* src, std::ptrdiff_t step, int width, int height,
                                                    const std::int16_t* xy, const std::uint16_t* frac,
                                                    std::uint8_t* dst, int n) {
  // The fast lanes: 0 <= sx <= width - 4 (a 4-byte gather stays in its row), 0 <= sy <= height - 2.
  const __m256i zero = _mm256_setzero_si256();
  const __m256i max_x = _mm256_set1_epi32(width - 4), max_y = _mm256_set1_epi32(height - 2);
  const __m256i row_step = _mm256_set1_epi32(static_cast<int>(step));
  const __m256i tab_mask = _mm256_set1_epi32(kTabMask), steps = _mm256_set1_epi32(32);
  const __m256i byte_mask = _mm256_set1_epi32(0xFF), half = _mm256_set1_epi32(512);
  const int* rows0 = reinterpret_cast<const int*>(src);
  const int* rows1 = reinterpret_cast<const int*>(src + step);
  int x = 0;
  for (; x + 8 <= n; x += 8) {
    const __m256i m = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(xy + 2 * x));
    const __m256i sx = _mm256_srai_epi32(_mm256_slli_epi32(m, 16), 16), sy = _mm256_srai_epi32(m, 16);
    __m256i top_pairs, bottom_pairs;
    if (!window_pairs(src, step, width, height, sx, sy, &top_pairs, &bottom_pairs)) {
      const __m256i outside =
          _mm256_or_si256(_mm256_or_si256(_mm256_cmpgt_epi32(zero, sx), _mm256_cmpgt_epi32(sx, max_x)),
                          _mm256_or_si256(_mm256_cmpgt_epi32(zero, sy), _mm256_cmpgt_epi32(sy, max_y)));
      if (!_mm256_testz_si256(outside, outside)) {
        remap_row(src, step, width, height, xy, frac, dst, x, x + 8);
        continue;
      }
      const __m256i offset = _mm256_add_epi32(_mm256_mullo_epi32(sy, row_step), sx);
      top_pairs = pixel_pairs(_mm256_i32gather_epi32(rows0, offset, 1), byte_mask);
      bottom_pairs = pixel_pairs(_mm256_i32gather_epi32(rows1, offset, 1), byte_mask);
    }
    const __m256i f = _mm256_cvtepu16_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(frac + x)));
    const __m256i fx = _mm256_and_si256(f, tab_mask), fy = _mm256_and_si256(_mm256_srli_epi32(f, kTabBits), tab_mask);
    const __m256i across = _mm256_or_si256(_mm256_sub_epi32(steps, fx), _mm256_slli_epi32(fx, 16));
    const __m256i up = _mm256_sub_epi32(steps, fy);
    const __m256i w_top = _mm256_mullo_epi16(across, _mm256_or_si256(up, _mm256_slli_epi32(up, 16)));
    const __m256i w_bottom = _mm256_mullo_epi16(across, _mm256_or_si256(fy, _mm256_slli_epi32(fy, 16)));
    __m256i v = _mm256_add_epi32(_mm256_madd_epi16(top_pairs, w_top), _mm256_madd_epi16(bottom_pairs, w_bottom));
    v = _mm256_srli_epi32(_mm256_add_epi32(v, half), 10);
    const __m256i words = _mm256_packus_epi32(v, v);          // per 128-bit half: 4 values, twice
    const __m256i bytes = _mm256_packus_epi16(words, words);  // per half: 4 bytes, four times
    const std::uint32_t low = static_cast<std::uint32_t>(_mm256_extract_epi32(bytes, 0));
    const std::uint32_t high = static_cast<std::uint32_t>(_mm256_extract_epi32(bytes, 4));
    std::memcpy(dst + x, &low, 4);
    std::memcpy(dst + x + 4, &high, 4);
  }
  remap_row(src, step, width, height, xy, frac, dst, x, n);
}

}  // namespace

void remap_bilinear(const cv::Mat& src, cv::Mat& dst, const cv::Mat& xy, const cv::Mat& frac, bool use_avx2) {
  ORBATLAS_CHECK(!src.empty() && src.type() == CV_8UC1, "remap_bilinear takes 8-bit grey images");
  ORBATLAS_CHECK(xy.type() == CV_16SC2 && frac.type() == CV_16UC1 && xy.size() == frac.size(),
                 "remap_bilinear takes cv::convertMaps' CV_16SC2 and CV_16UC1 maps of one size");
  ORBATLAS_CHECK(dst.data != src.data || dst.empty(), "remap_bilinear cannot remap in place");
  dst.create(xy.size(), CV_8UC1);
  const auto step = static_cast<std::ptrdiff_t>(src.step);
  const bool avx2 = use_avx2 && cpu_has_avx2();
  for (int y = 0; y < dst.rows; ++y) {
    const auto* row_xy = xy.ptr<std::int16_t>(y);
    const auto* row_frac = frac.ptr<std::uint16_t>(y);
    auto* out = dst.ptr<std::uint8_t>(y);
    if (avx2)
      remap_row_avx2(src.data, step, src.cols, src.rows, row_xy, row_frac, out, dst.cols);
    else
      remap_row(src.data, step, src.cols, src.rows, row_xy, row_frac, out, 0, dst.cols);
  }
}

}  // namespace orbatlas
