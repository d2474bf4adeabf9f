#pragma once
// 256-bit binary descriptors (rotated BRIEF, as in ORB) and their Hamming distance.
#include <array>
#include <bit>
#include <cstdint>
#include <opencv2/core/mat.hpp>
#include <vector>

namespace orbatlas {

using Descriptor = std::array<std::uint64_t, 4>;

inline int hamming(const Descriptor& a, const Descriptor& b) {
  return std::popcount(a[0] ^ b[0]) + std::popcount(a[1] ^ b[1]) + std::popcount(a[2] ^ b[2]) +
         std::popcount(a[3] ^ b[3]);
}

// Matching thresholds used across the system (ORB-SLAM's TH_LOW / TH_HIGH).
constexpr int kHammingLow = 50;
constexpr int kHammingHigh = 100;

// OpenCV's ORB layout: one CV_8UC1 row of 32 bytes per descriptor.
std::vector<Descriptor> descriptors_from_mat(const cv::Mat& rows);
cv::Mat descriptors_to_mat(const std::vector<Descriptor>& descriptors);

}  // namespace orbatlas
