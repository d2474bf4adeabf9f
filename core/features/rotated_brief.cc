// OpenCV's computeOrbDescriptors, re-derived: angle in radians as a float times
// (float)(pi / 180), a = cos, b = sin as floats, a point (px, py) lands at
// (round(px a - py b), round(px b + py a)) with round-half-even, and the test is
// I(first) < I(second). tests/features/test_rotated_brief.cc holds us to OpenCV's bits.
#include "core/features/rotated_brief.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define ORBATLAS_BRIEF_AVX2 1
#endif

#include <opencv2/imgproc.hpp>

#include "core/common/error.h"
#include "core/features/brief_blur.h"
#include "core/features/cpu_features.h"

namespace orbatlas {
namespace {

struct Rotation {
  float a, b;  // cos and sin of the angle, as OpenCV rounds them
};

Rotation rotation(float angle_deg) {
  const float radians = angle_deg * static_cast<float>(CV_PI / 180.f);
  return {static_cast<float>(std::cos(static_cast<double>(radians))),
          static_cast<float>(std::sin(static_cast<double>(radians)))};
}

#if defined(ORBATLAS_BRIEF_AVX2)
__attribute__((target("avx2"))) inline __m256i turned_pixels(const std::uint8_t* center, __m256 px, __m256 py, __m256 a,
                                                             __m256 b, __m256i step) {
  const __m256 x = _mm256_sub_ps(_mm256_mul_ps(px, a), _mm256_mul_ps(py, b));
  const __m256 y = _mm256_add_ps(_mm256_mul_ps(px, b), _mm256_mul_ps(py, a));
  const __m256i offsets = _mm256_add_epi32(_mm256_mullo_epi32(_mm256_cvtps_epi32(y), step), _mm256_cvtps_epi32(x));
  // Four bytes read at each offset (inside the image: see describe()), the first kept.
  const __m256i words = _mm256_i32gather_epi32(reinterpret_cast<const int*>(center), offsets, 1);
  return _mm256_and_si256(words, _mm256_set1_epi32(0xff));
}

__attribute__((target("avx2"))) void describe_avx2(const std::uint8_t* center, std::ptrdiff_t step, Rotation r,
                                                   const float* first_x, const float* first_y, const float* second_x,
                                                   const float* second_y, std::uint8_t* out) {
  const __m256 a = _mm256_set1_ps(r.a), b = _mm256_set1_ps(r.b);
  const __m256i stepv = _mm256_set1_epi32(static_cast<int>(step));
  for (int j = 0; j < BriefPattern::kPairs / 8; ++j) {
    const __m256i first =
        turned_pixels(center, _mm256_load_ps(first_x + 8 * j), _mm256_load_ps(first_y + 8 * j), a, b, stepv);
    const __m256i second =
        turned_pixels(center, _mm256_load_ps(second_x + 8 * j), _mm256_load_ps(second_y + 8 * j), a, b, stepv);
    out[j] = static_cast<std::uint8_t>(_mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(second, first))));
  }
}
#endif

}  // namespace

RotatedBrief::RotatedBrief(const BriefPattern& pattern) {
  float reach = 0;
  for (int i = 0; i < BriefPattern::kPairs; ++i) {
    const auto f = static_cast<std::size_t>(2 * i), s = f + 1, k = static_cast<std::size_t>(i);
    first_x_[k] = pattern.x[f];
    first_y_[k] = pattern.y[f];
    second_x_[k] = pattern.x[s];
    second_y_[k] = pattern.y[s];
    reach = std::max({reach, std::hypot(first_x_[k], first_y_[k]), std::hypot(second_x_[k], second_y_[k])});
  }
  // A turned point rounds to at most the nearest whole pixel beyond its distance.
  reach_ = static_cast<int>(std::floor(reach + 0.5f));
}

namespace {

void check_level_view(const cv::Mat& level_view, const cv::Mat& dst) {
  constexpr int kRadius = 3;
  ORBATLAS_CHECK(!level_view.empty() && level_view.type() == CV_8UC1,
                 "rotated BRIEF: the level must be a non-empty CV_8UC1 image");
  cv::Size whole;
  cv::Point offset;
  level_view.locateROI(whole, offset);
  ORBATLAS_CHECK(
      offset.x >= kRadius && offset.y >= kRadius && whole.width - offset.x - level_view.cols >= kRadius &&
          whole.height - offset.y - level_view.rows >= kRadius,
      "rotated BRIEF: the level needs " << kRadius << " valid pixels on every side (a view of a bordered buffer)");
  ORBATLAS_CHECK(dst.empty() || dst.datastart != level_view.datastart,
                 "rotated BRIEF: the blurred level must not share the level's memory");
}

}  // namespace

void RotatedBrief::blur(const cv::Mat& level_view, cv::Mat& dst, bool use_avx2) {
  check_level_view(level_view, dst);
  brief_blur(level_view, dst, use_avx2);
}

void RotatedBrief::blur_as_opencv(const cv::Mat& level_view, cv::Mat& dst) {
  check_level_view(level_view, dst);
  cv::GaussianBlur(level_view, dst, cv::Size(7, 7), 2, 2, cv::BORDER_REFLECT_101);
}

Descriptor RotatedBrief::describe(const cv::Mat& blurred, int x, int y, float angle_deg, bool use_avx2) const {
  // reach_ + 1 below and right: the AVX2 path reads four bytes at each point.
  ORBATLAS_CHECK(blurred.type() == CV_8UC1 && x >= reach_ && y >= reach_ && x + reach_ + 1 < blurred.cols &&
                     y + reach_ + 1 < blurred.rows,
                 "rotated BRIEF: keypoint (" << x << ", " << y << ") is within " << reach_ << " px of the edge of a "
                                             << blurred.cols << "x" << blurred.rows << " image");
  const Rotation r = rotation(angle_deg);
  const std::uint8_t* center = blurred.ptr<std::uint8_t>(y) + x;
  const auto step = static_cast<std::ptrdiff_t>(blurred.step1());
  Descriptor d{};
  std::uint8_t bytes[32];
#if defined(ORBATLAS_BRIEF_AVX2)
  if (use_avx2 && cpu_has_avx2()) {
    describe_avx2(center, step, r, first_x_.data(), first_y_.data(), second_x_.data(), second_y_.data(), bytes);
    std::memcpy(d.data(), bytes, sizeof(bytes));
    return d;
  }
#endif
  (void)use_avx2;
  const auto value = [&](float px, float py) {
    const float tx = px * r.a - py * r.b, ty = px * r.b + py * r.a;
    return center[std::lrint(ty) * step + std::lrint(tx)];
  };
  for (int j = 0; j < BriefPattern::kPairs / 8; ++j) {
    int byte = 0;
    for (int k = 0; k < 8; ++k) {
      const auto i = static_cast<std::size_t>(8 * j + k);
      byte |= (value(first_x_[i], first_y_[i]) < value(second_x_[i], second_y_[i]) ? 1 : 0) << k;
    }
    bytes[j] = static_cast<std::uint8_t>(byte);
  }
  std::memcpy(d.data(), bytes, sizeof(bytes));
  return d;
}

}  // namespace orbatlas
