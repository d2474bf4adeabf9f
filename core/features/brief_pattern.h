#pragma once
// The point pairs of ORB's rotated BRIEF (patch 31, 256 tests), as the installed
// OpenCV uses them. Bit i of a descriptor is 1 when the blurred level image is
// darker at pair i's first point than at its second, both turned by the
// keypoint's angle. The shipped vocabulary and every stored descriptor depend on
// exactly these pairs, so ours must be OpenCV's: they are learned from the
// installed library by probing cv::ORB (no copy of OpenCV's table is kept).
#include <array>
#include <cstdint>

namespace orbatlas {

struct BriefPattern {
  static constexpr int kPairs = 256;
  // Pair i: first point (x[2i], y[2i]), second point (x[2i + 1], y[2i + 1]),
  // in pixels from the keypoint at angle 0.
  std::array<std::int8_t, 2 * kPairs> x{}, y{};
};

// Probes cv::ORB::compute with images that are dark but for one bright pixel
// (and bright but for one dark pixel) at each offset of the 31x31 patch: a test
// turns 1 only near its second point (first point); the pair that explains
// every probe's bits is the test's. Throws Error when the probes are not
// explained by exactly one pair per test (an OpenCV whose ORB differs). A few
// milliseconds.
BriefPattern learn_opencv_brief_pattern();

// learn_opencv_brief_pattern(), once per process (immutable afterwards).
const BriefPattern& opencv_brief_pattern();

}  // namespace orbatlas
