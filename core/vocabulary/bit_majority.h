#pragma once
// Internal to the vocabulary library: per-bit counts over a set of descriptors and
// their bitwise majority (the k-medians centre under the Hamming distance).
// Counting goes through byte lanes: each descriptor byte adds a table entry that
// spreads its 8 bits over the 8 bytes of a 64-bit word, so a descriptor costs 32
// additions instead of 256; the lanes are flushed before a byte can overflow.
#include <array>
#include <cstdint>

#include "core/features/descriptor.h"

namespace orbatlas::vocabulary_detail {

// kSpreadBits[v]: byte j is bit j of v.
constexpr std::array<std::uint64_t, 256> make_spread_bits() {
  std::array<std::uint64_t, 256> t{};
  for (int v = 0; v < 256; ++v)
    for (int j = 0; j < 8; ++j)
      if ((v >> j) & 1) t[v] |= std::uint64_t{1} << (8 * j);
  return t;
}
inline constexpr std::array<std::uint64_t, 256> kSpreadBits = make_spread_bits();

class BitMajority {
 public:
  void add(const Descriptor& d) {
    for (int w = 0; w < 4; ++w)
      for (int b = 0; b < 8; ++b) lanes_[w * 8 + b] += kSpreadBits[(d[w] >> (8 * b)) & 0xFF];
    ++size_;
    if (++pending_ == 255) flush();
  }
  // Adds the counts of `other` (which is left flushed).
  void merge(BitMajority& other) {
    flush();
    other.flush();
    for (int i = 0; i < 256; ++i) counts_[i] += other.counts_[i];
    size_ += other.size_;
  }
  void clear() { *this = BitMajority(); }
  std::uint32_t size() const { return size_; }
  // Bit i is set when more than half of the descriptors have it set.
  Descriptor majority() {
    flush();
    Descriptor m{};
    for (int i = 0; i < 256; ++i)
      if (2 * static_cast<std::uint64_t>(counts_[i]) > size_) m[i / 64] |= std::uint64_t{1} << (i % 64);
    return m;
  }

 private:
  void flush() {
    for (int lane = 0; lane < 32; ++lane) {
      for (int j = 0; j < 8; ++j) counts_[lane * 8 + j] += static_cast<std::uint32_t>((lanes_[lane] >> (8 * j)) & 0xFF);
      lanes_[lane] = 0;
    }
    pending_ = 0;
  }

  std::array<std::uint32_t, 256> counts_{};  // bit i of the descriptor: word i / 64, bit i % 64
  std::array<std::uint64_t, 32> lanes_{};    // lane w * 8 + b: byte b of word w, one byte counter per bit
  std::uint32_t pending_ = 0, size_ = 0;
};

}  // namespace orbatlas::vocabulary_detail
