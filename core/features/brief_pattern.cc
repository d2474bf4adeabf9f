// Learning OpenCV's BRIEF pairs from its ORB. ORB blurs the image 7x7 (sigma 2)
// before its tests, so a single bright pixel at offset q becomes a small bump
// B(p - q), positive exactly where |p - q| <= 3 in both axes and highest at q.
// A test (first point a, second point b) reads 1 on that probe when B(a - q) <
// B(b - q): only for q within 3 px of b, and always for q = b. On the dark
// probes (a dip D) it reads 1 only near a, and always for q = a. Each point is
// thus confined to the few offsets within 3 px of every probe that turned its
// test on; the candidate pairs are then checked against every probe's bit,
// with B and D taken from cv::GaussianBlur itself.
#include "core/features/brief_pattern.h"

#include <cstdlib>
#include <cstring>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "core/common/error.h"

namespace orbatlas {
namespace {

constexpr int kReach = 15;              // ORB's 31-px patch: every point within +-15 px
constexpr int kSide = 2 * kReach + 1;   // offsets per axis
constexpr int kProbes = kSide * kSide;  // one keypoint per offset
constexpr int kBlurRadius = 3;          // the 7x7 blur
constexpr int kCell = 48;               // keypoints this far apart: patch + blur never reach a neighbour
constexpr int kMargin = 48;             // beyond ORB's edge threshold

struct Offset {
  int x, y;
};

Offset probe_offset(int probe) { return {probe % kSide - kReach, probe / kSide - kReach}; }

cv::Point probe_center(int probe) {
  return {kMargin + (probe % kSide) * kCell + kCell / 2, kMargin + (probe / kSide) * kCell + kCell / 2};
}

// The bits of each probe's descriptor: probe images with `background` everywhere
// but `spot` at each keypoint's probe offset.
std::vector<std::array<std::uint8_t, 32>> probe_bits(std::uint8_t background, std::uint8_t spot) {
  const int size = 2 * kMargin + kSide * kCell;
  cv::Mat image(size, size, CV_8UC1, cv::Scalar(background));
  std::vector<cv::KeyPoint> keys;
  keys.reserve(kProbes);
  for (int p = 0; p < kProbes; ++p) {
    const cv::Point c = probe_center(p);
    const Offset q = probe_offset(p);
    image.at<std::uint8_t>(c.y + q.y, c.x + q.x) = spot;
    keys.emplace_back(static_cast<float>(c.x), static_cast<float>(c.y), 31.0f, 0.0f, 1.0f, 0);
  }
  const cv::Ptr<cv::ORB> orb = cv::ORB::create(kProbes, 1.2f, 1, 31, 0, 2, cv::ORB::HARRIS_SCORE, 31);
  cv::Mat descriptors;
  orb->compute(image, keys, descriptors);
  ORBATLAS_CHECK(
      static_cast<int>(keys.size()) == kProbes && descriptors.rows == kProbes && descriptors.cols == 32 &&
          descriptors.type() == CV_8UC1,
      "learning OpenCV's BRIEF pattern: cv::ORB kept " << keys.size() << " of " << kProbes << " probe keypoints");
  std::vector<std::array<std::uint8_t, 32>> bits(kProbes);
  for (int r = 0; r < kProbes; ++r) {
    // Rows follow the keypoints; map each back to its probe by position.
    const int col = (static_cast<int>(keys[static_cast<std::size_t>(r)].pt.x) - kMargin) / kCell;
    const int row = (static_cast<int>(keys[static_cast<std::size_t>(r)].pt.y) - kMargin) / kCell;
    const int p = row * kSide + col;
    ORBATLAS_CHECK(p >= 0 && p < kProbes &&
                       probe_center(p) == cv::Point(static_cast<int>(keys[static_cast<std::size_t>(r)].pt.x),
                                                    static_cast<int>(keys[static_cast<std::size_t>(r)].pt.y)),
                   "learning OpenCV's BRIEF pattern: cv::ORB moved a probe keypoint");
    std::memcpy(bits[static_cast<std::size_t>(p)].data(), descriptors.ptr(r), 32);
  }
  return bits;
}

// The blurred probe around its spot: response[dy + 3][dx + 3]; `background` beyond.
struct BlurredSpot {
  int response[2 * kBlurRadius + 1][2 * kBlurRadius + 1];
  int background;
  int at(int dx, int dy) const {
    if (std::abs(dx) > kBlurRadius || std::abs(dy) > kBlurRadius) return background;
    return response[dy + kBlurRadius][dx + kBlurRadius];
  }
};

BlurredSpot blurred_spot(std::uint8_t background, std::uint8_t spot) {
  cv::Mat image(31, 31, CV_8UC1, cv::Scalar(background)), blurred;
  image.at<std::uint8_t>(15, 15) = spot;
  cv::GaussianBlur(image, blurred, cv::Size(7, 7), 2, 2, cv::BORDER_REFLECT_101);
  BlurredSpot out{};
  out.background = background;
  for (int dy = -kBlurRadius; dy <= kBlurRadius; ++dy)
    for (int dx = -kBlurRadius; dx <= kBlurRadius; ++dx) {
      out.response[dy + kBlurRadius][dx + kBlurRadius] = blurred.at<std::uint8_t>(15 + dy, 15 + dx);
      ORBATLAS_CHECK(out.response[dy + kBlurRadius][dx + kBlurRadius] != background,
                     "learning OpenCV's BRIEF pattern: the 7x7 blur does not reach (" << dx << ", " << dy << ")");
    }
  return out;
}

bool bit(const std::array<std::uint8_t, 32>& d, int pair) {
  return (d[static_cast<std::size_t>(pair / 8)] >> (pair % 8)) & 1;
}

// The offsets within the blur's reach of every probe in `on` (empty: none).
std::vector<Offset> near_all(const std::vector<Offset>& on) {
  std::vector<Offset> out;
  if (on.empty()) return out;
  for (int p = 0; p < kProbes; ++p) {
    const Offset c = probe_offset(p);
    bool ok = true;
    for (const Offset& q : on)
      if (std::abs(c.x - q.x) > kBlurRadius || std::abs(c.y - q.y) > kBlurRadius) {
        ok = false;
        break;
      }
    if (ok) out.push_back(c);
  }
  return out;
}

}  // namespace

BriefPattern learn_opencv_brief_pattern() {
  const auto bright_bits = probe_bits(0, 255), dark_bits = probe_bits(255, 0);
  const BlurredSpot bump = blurred_spot(0, 255), dip = blurred_spot(255, 0);
  BriefPattern pattern;
  for (int i = 0; i < BriefPattern::kPairs; ++i) {
    std::vector<Offset> second_on, first_on;
    for (int p = 0; p < kProbes; ++p) {
      if (bit(bright_bits[static_cast<std::size_t>(p)], i)) second_on.push_back(probe_offset(p));
      if (bit(dark_bits[static_cast<std::size_t>(p)], i)) first_on.push_back(probe_offset(p));
    }
    const std::vector<Offset> seconds = near_all(second_on), firsts = near_all(first_on);
    int found = 0;
    Offset first{}, second{};
    for (const Offset& a : firsts)
      for (const Offset& b : seconds) {
        bool consistent = true;
        for (int p = 0; p < kProbes && consistent; ++p) {
          const Offset q = probe_offset(p);
          const bool bright = bump.at(a.x - q.x, a.y - q.y) < bump.at(b.x - q.x, b.y - q.y);
          const bool dark = dip.at(a.x - q.x, a.y - q.y) < dip.at(b.x - q.x, b.y - q.y);
          consistent = bright == bit(bright_bits[static_cast<std::size_t>(p)], i) &&
                       dark == bit(dark_bits[static_cast<std::size_t>(p)], i);
        }
        if (consistent) {
          ++found;
          first = a;
          second = b;
        }
      }
    ORBATLAS_CHECK(found == 1, "learning OpenCV's BRIEF pattern: test " << i << " is explained by " << found
                                                                        << " point pairs, not one");
    pattern.x[static_cast<std::size_t>(2 * i)] = static_cast<std::int8_t>(first.x);
    pattern.y[static_cast<std::size_t>(2 * i)] = static_cast<std::int8_t>(first.y);
    pattern.x[static_cast<std::size_t>(2 * i + 1)] = static_cast<std::int8_t>(second.x);
    pattern.y[static_cast<std::size_t>(2 * i + 1)] = static_cast<std::int8_t>(second.y);
  }
  return pattern;
}

const BriefPattern& opencv_brief_pattern() {
  static const BriefPattern pattern = learn_opencv_brief_pattern();  // learned once, never changed
  return pattern;
}

}  // namespace orbatlas
