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
#if defined(__POPCNT__) || !defined(__x86_64__)
  return std::popcount(a[0] ^ b[0]) + std::popcount(a[1] ^ b[1]) + std::popcount(a[2] ^ b[2]) +
         std::popcount(a[3] ^ b[3]);
#else
  // Built for baseline x86-64 (no POPCNT), std::popcount is a call into libgcc's
  // table per word. This counts each word's bits per byte in registers, adds
  // the four words' byte counts (at most 32 each), then the bytes in pairs
  // (at most 64 each) and the pairs with one multiply (at most 256).
  constexpr std::uint64_t m1 = 0x5555555555555555u, m2 = 0x3333333333333333u, m4 = 0x0f0f0f0f0f0f0f0fu;
  constexpr std::uint64_t m8 = 0x00ff00ff00ff00ffu, h16 = 0x0001000100010001u;
  std::uint64_t bytes = 0;
  for (std::size_t i = 0; i < 4; ++i) {
    std::uint64_t x = a[i] ^ b[i];
    x -= (x >> 1) & m1;
    x = (x & m2) + ((x >> 2) & m2);
    bytes += (x + (x >> 4)) & m4;
  }
  const std::uint64_t pairs = (bytes & m8) + ((bytes >> 8) & m8);
  return static_cast<int>((pairs * h16) >> 48);
#endif
}

// Matching thresholds used across the system (ORB-SLAM's TH_LOW / TH_HIGH).
constexpr int kHammingLow = 50;
constexpr int kHammingHigh = 100;

// OpenCV's ORB layout: one CV_8UC1 row of 32 bytes per descriptor.
std::vector<Descriptor> descriptors_from_mat(const cv::Mat& rows);
cv::Mat descriptors_to_mat(const std::vector<Descriptor>& descriptors);

}  // namespace orbatlas
