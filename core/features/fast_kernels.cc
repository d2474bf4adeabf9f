// The FAST-9 score map and the per-cell non-maximum suppression of the ORB
// extractor (fast_kernels.h): scalar, SSE2 and AVX2 paths giving the same bytes.
#include "core/features/fast_kernels.h"

#include <algorithm>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define ORBATLAS_FAST_AVX2 1
#endif

#include "core/features/cpu_features.h"

namespace orbatlas {
namespace {

// ---- FAST-9 scores ----

std::uint8_t fast_score_scalar(const std::uint8_t* p, const std::ptrdiff_t* offsets) {
  const int v = p[0];
  int bright[16], dark[16];
  for (int k = 0; k < 16; ++k) {
    const int c = p[offsets[k]];
    bright[k] = std::max(c - v, 0);
    dark[k] = std::max(v - c, 0);
  }
  int best = 0;
  for (int s = 0; s < 16; ++s) {
    int b = 255, d = 255;
    for (int j = 0; j < 9; ++j) {
      b = std::min(b, bright[(s + j) & 15]);
      d = std::min(d, dark[(s + j) & 15]);
    }
    best = std::max(best, std::max(b, d));
  }
  return static_cast<std::uint8_t>(std::max(best - 1, 0));
}

#if defined(__SSE2__)
// Per lane: the best over the 16 arcs of 9 of the arc's minimum (saturated differences).
inline __m128i best_arc(const __m128i x[16]) {
  __m128i m2[16], m4[16];
  for (int k = 0; k < 16; ++k) m2[k] = _mm_min_epu8(x[k], x[(k + 1) & 15]);
  for (int k = 0; k < 16; ++k) m4[k] = _mm_min_epu8(m2[k], m2[(k + 2) & 15]);
  __m128i best = _mm_setzero_si128();
  for (int k = 0; k < 16; ++k)
    best = _mm_max_epu8(best, _mm_min_epu8(_mm_min_epu8(m4[k], m4[(k + 4) & 15]), x[(k + 8) & 15]));
  return best;
}

// Scores of the 16 pixels p[0..15]; all zero when none can be a corner at min_t.
inline __m128i fast_scores16(const std::uint8_t* p, const std::ptrdiff_t* offsets, __m128i min_t) {
  const auto load = [&](std::ptrdiff_t o) { return _mm_loadu_si128(reinterpret_cast<const __m128i*>(p + o)); };
  const __m128i zero = _mm_setzero_si128();
  const __m128i v = load(0);
  // FAST's quick test: a corner has two neighbouring compass points of the
  // circle (pixels 0, 4, 8, 12) both beyond the threshold in the same direction.
  const __m128i hi = _mm_adds_epu8(v, min_t), lo = _mm_subs_epu8(v, min_t);
  __m128i b[4], d[4];
  for (int q = 0; q < 4; ++q) {
    const __m128i c = load(offsets[4 * q]);
    b[q] = _mm_subs_epu8(c, hi);
    d[q] = _mm_subs_epu8(lo, c);
  }
  __m128i any = zero;
  for (int q = 0; q < 4; ++q) {
    any = _mm_max_epu8(any, _mm_min_epu8(b[q], b[(q + 1) & 3]));
    any = _mm_max_epu8(any, _mm_min_epu8(d[q], d[(q + 1) & 3]));
  }
  if (_mm_movemask_epi8(_mm_cmpeq_epi8(any, zero)) == 0xffff) return zero;
  __m128i x[16];
  for (int k = 0; k < 16; ++k) x[k] = _mm_subs_epu8(load(offsets[k]), v);
  const __m128i bright = best_arc(x);
  for (int k = 0; k < 16; ++k) x[k] = _mm_subs_epu8(v, load(offsets[k]));
  const __m128i dark = best_arc(x);
  return _mm_subs_epu8(_mm_max_epu8(bright, dark), _mm_set1_epi8(1));
}
#endif

#if defined(ORBATLAS_FAST_AVX2)
// The same as best_arc and fast_scores16 on 32 pixels at once, for CPUs with
// AVX2 (chosen at run time; the results are the same bytes).
__attribute__((target("avx2"))) inline __m256i best_arc32(const __m256i x[16]) {
  __m256i m2[16], m4[16];
  for (int k = 0; k < 16; ++k) m2[k] = _mm256_min_epu8(x[k], x[(k + 1) & 15]);
  for (int k = 0; k < 16; ++k) m4[k] = _mm256_min_epu8(m2[k], m2[(k + 2) & 15]);
  __m256i best = _mm256_setzero_si256();
  for (int k = 0; k < 16; ++k)
    best = _mm256_max_epu8(best, _mm256_min_epu8(_mm256_min_epu8(m4[k], m4[(k + 4) & 15]), x[(k + 8) & 15]));
  return best;
}

__attribute__((target("avx2"))) inline __m256i fast_scores32(const std::uint8_t* p, const std::ptrdiff_t* offsets,
                                                             __m256i min_t) {
  // (No lambda: it would not inherit the function's target.)
#define ORBATLAS_LOAD32(o) _mm256_loadu_si256(reinterpret_cast<const __m256i*>(p + (o)))
  const __m256i zero = _mm256_setzero_si256();
  const __m256i v = ORBATLAS_LOAD32(0);
  const __m256i hi = _mm256_adds_epu8(v, min_t), lo = _mm256_subs_epu8(v, min_t);
  __m256i b[4], d[4];
  for (int q = 0; q < 4; ++q) {
    const __m256i c = ORBATLAS_LOAD32(offsets[4 * q]);
    b[q] = _mm256_subs_epu8(c, hi);
    d[q] = _mm256_subs_epu8(lo, c);
  }
  __m256i any = zero;
  for (int q = 0; q < 4; ++q) {
    any = _mm256_max_epu8(any, _mm256_min_epu8(b[q], b[(q + 1) & 3]));
    any = _mm256_max_epu8(any, _mm256_min_epu8(d[q], d[(q + 1) & 3]));
  }
  if (static_cast<unsigned>(_mm256_movemask_epi8(_mm256_cmpeq_epi8(any, zero))) == 0xffffffffu) return zero;
  __m256i x[16];
  for (int k = 0; k < 16; ++k) x[k] = _mm256_subs_epu8(ORBATLAS_LOAD32(offsets[k]), v);
  const __m256i bright = best_arc32(x);
  for (int k = 0; k < 16; ++k) x[k] = _mm256_subs_epu8(v, ORBATLAS_LOAD32(offsets[k]));
  const __m256i dark = best_arc32(x);
#undef ORBATLAS_LOAD32
  return _mm256_subs_epu8(_mm256_max_epu8(bright, dark), _mm256_set1_epi8(1));
}

// Scores of row[x_begin, x_end) 32 at a time (x_end - x_begin >= 32).
__attribute__((target("avx2"))) void fast_score_row_avx2(const std::uint8_t* row, const std::ptrdiff_t* offsets,
                                                         int x_begin, int x_end, std::uint8_t* out, int min_threshold) {
  const __m256i min_t = _mm256_set1_epi8(static_cast<char>(min_threshold));
  for (int x = x_begin;; x += 32) {
    if (x + 32 > x_end) x = x_end - 32;  // the last block overlaps the one before
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(out + x), fast_scores32(row + x, offsets, min_t));
    if (x + 32 == x_end) return;
  }
}

#endif

}  // namespace

void fast_circle_offsets(std::ptrdiff_t row_step, std::ptrdiff_t offsets[16]) {
  // The Bresenham circle of radius 3, in order around the centre (dx, dy).
  constexpr int kCircle[16][2] = {{0, 3},  {1, 3},   {2, 2},   {3, 1},   {3, 0},  {3, -1}, {2, -2}, {1, -3},
                                  {0, -3}, {-1, -3}, {-2, -2}, {-3, -1}, {-3, 0}, {-3, 1}, {-2, 2}, {-1, 3}};
  for (int k = 0; k < 16; ++k) offsets[k] = kCircle[k][1] * row_step + kCircle[k][0];
}

void fast_score_row(const std::uint8_t* row, const std::ptrdiff_t* offsets, int x_begin, int x_end, std::uint8_t* out,
                    int min_threshold, bool use_avx2) {
  int x = x_begin;
#if defined(ORBATLAS_FAST_AVX2)
  if (use_avx2 && x_end - x_begin >= 32 && cpu_has_avx2()) {
    fast_score_row_avx2(row, offsets, x_begin, x_end, out, min_threshold);
    return;
  }
#endif
#if defined(__SSE2__)
  if (x_end - x_begin >= 16) {
    const __m128i min_t = _mm_set1_epi8(static_cast<char>(min_threshold));
    for (;; x += 16) {
      if (x + 16 > x_end) x = x_end - 16;  // the last block overlaps the one before
      _mm_storeu_si128(reinterpret_cast<__m128i*>(out + x), fast_scores16(row + x, offsets, min_t));
      if (x + 16 == x_end) return;
    }
  }
#else
  (void)min_threshold;
#endif
  (void)use_avx2;
  for (; x < x_end; ++x) out[x] = fast_score_scalar(row + x, offsets);
}

namespace {

// ---- Non-maximum suppression ----

inline void set_bits(std::uint64_t* bits, int x, std::uint64_t mask, int lanes) {
  const int shift = x & 63;
  bits[x >> 6] |= mask << shift;
  if (shift > 64 - lanes) bits[(x >> 6) + 1] |= mask >> (64 - shift);
}

void maxima_row_scalar(const std::uint8_t* up, const std::uint8_t* row, const std::uint8_t* down,
                       const std::uint8_t* left_ok, const std::uint8_t* right_ok, int x_begin, int x_end, int threshold,
                       std::uint64_t* bits) {
  for (int x = x_begin; x < x_end; ++x) {
    const int c = row[x];
    if (c < threshold) continue;
    int m = std::max(up[x], down[x]);
    if (left_ok[x] != 0)
      m = std::max({m, static_cast<int>(row[x - 1]), static_cast<int>(up[x - 1]), static_cast<int>(down[x - 1])});
    if (right_ok[x] != 0)
      m = std::max({m, static_cast<int>(row[x + 1]), static_cast<int>(up[x + 1]), static_cast<int>(down[x + 1])});
    if (c > m) bits[x >> 6] |= std::uint64_t{1} << (x & 63);
  }
}

#if defined(__SSE2__)
// 16 pixels at a time (x_end - x_begin >= 16; the last block overlaps the one before).
void maxima_row_sse2(const std::uint8_t* up, const std::uint8_t* row, const std::uint8_t* down,
                     const std::uint8_t* left_ok, const std::uint8_t* right_ok, int x_begin, int x_end, int threshold,
                     std::uint64_t* bits) {
  const auto load = [](const std::uint8_t* p) { return _mm_loadu_si128(reinterpret_cast<const __m128i*>(p)); };
  const __m128i th = _mm_set1_epi8(static_cast<char>(threshold)), zero = _mm_setzero_si128();
  for (int x = x_begin;; x += 16) {
    if (x + 16 > x_end) x = x_end - 16;
    const __m128i c = load(row + x), l = load(left_ok + x), r = load(right_ok + x);
    __m128i m = _mm_max_epu8(load(up + x), load(down + x));
    m = _mm_max_epu8(
        m, _mm_and_si128(l, _mm_max_epu8(load(row + x - 1), _mm_max_epu8(load(up + x - 1), load(down + x - 1)))));
    m = _mm_max_epu8(
        m, _mm_and_si128(r, _mm_max_epu8(load(row + x + 1), _mm_max_epu8(load(up + x + 1), load(down + x + 1)))));
    // c >= threshold and c > m (unsigned: c - m does not saturate to zero).
    const __m128i keep =
        _mm_andnot_si128(_mm_cmpeq_epi8(_mm_subs_epu8(c, m), zero), _mm_cmpeq_epi8(_mm_max_epu8(c, th), c));
    const auto mask = static_cast<std::uint64_t>(static_cast<unsigned>(_mm_movemask_epi8(keep)));
    if (mask != 0) set_bits(bits, x, mask, 16);
    if (x + 16 == x_end) return;
  }
}
#endif

#if defined(ORBATLAS_FAST_AVX2)
// The same 32 pixels at a time (x_end - x_begin >= 32).
__attribute__((target("avx2"))) void maxima_row_avx2(const std::uint8_t* up, const std::uint8_t* row,
                                                     const std::uint8_t* down, const std::uint8_t* left_ok,
                                                     const std::uint8_t* right_ok, int x_begin, int x_end,
                                                     int threshold, std::uint64_t* bits) {
#define ORBATLAS_LOAD32(p) _mm256_loadu_si256(reinterpret_cast<const __m256i*>(p))
  const __m256i th = _mm256_set1_epi8(static_cast<char>(threshold)), zero = _mm256_setzero_si256();
  for (int x = x_begin;; x += 32) {
    if (x + 32 > x_end) x = x_end - 32;
    const __m256i c = ORBATLAS_LOAD32(row + x), l = ORBATLAS_LOAD32(left_ok + x), r = ORBATLAS_LOAD32(right_ok + x);
    const __m256i strong = _mm256_cmpeq_epi8(_mm256_max_epu8(c, th), c);  // c >= threshold
    __m256i m = _mm256_max_epu8(ORBATLAS_LOAD32(up + x), ORBATLAS_LOAD32(down + x));
    m = _mm256_max_epu8(m, _mm256_and_si256(l, _mm256_max_epu8(ORBATLAS_LOAD32(row + x - 1),
                                                               _mm256_max_epu8(ORBATLAS_LOAD32(up + x - 1),
                                                                               ORBATLAS_LOAD32(down + x - 1)))));
    m = _mm256_max_epu8(m, _mm256_and_si256(r, _mm256_max_epu8(ORBATLAS_LOAD32(row + x + 1),
                                                               _mm256_max_epu8(ORBATLAS_LOAD32(up + x + 1),
                                                                               ORBATLAS_LOAD32(down + x + 1)))));
    const __m256i keep = _mm256_andnot_si256(_mm256_cmpeq_epi8(_mm256_subs_epu8(c, m), zero), strong);
    const auto mask = static_cast<std::uint64_t>(static_cast<unsigned>(_mm256_movemask_epi8(keep)));
    if (mask != 0) set_bits(bits, x, mask, 32);
    if (x + 32 == x_end) return;
  }
#undef ORBATLAS_LOAD32
}
#endif

}  // namespace

void maxima_row(const std::uint8_t* up, const std::uint8_t* row, const std::uint8_t* down, const std::uint8_t* left_ok,
                const std::uint8_t* right_ok, int x_begin, int x_end, int threshold, std::uint64_t* bits,
                bool use_avx2) {
#if defined(ORBATLAS_FAST_AVX2)
  if (use_avx2 && x_end - x_begin >= 32 && cpu_has_avx2()) {
    maxima_row_avx2(up, row, down, left_ok, right_ok, x_begin, x_end, threshold, bits);
    return;
  }
#endif
  (void)use_avx2;
#if defined(__SSE2__)
  if (x_end - x_begin >= 16) {
    maxima_row_sse2(up, row, down, left_ok, right_ok, x_begin, x_end, threshold, bits);
    return;
  }
#endif
  maxima_row_scalar(up, row, down, left_ok, right_ok, x_begin, x_end, threshold, bits);
}

}  // namespace orbatlas
