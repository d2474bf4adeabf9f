#pragma once
// A set of 64-bit ids for one pass of a hot loop (tracking's local-map points,
// tens of thousands a frame): open addressing with linear probing in one flat
// array that is kept between passes, so an insert neither allocates nor
// follows a pointer (std::unordered_set did both, 1.8 % of a loaded server's
// samples). Not thread-safe: one owner.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

namespace orbatlas {

class FlatIdSet {
 public:
  // The value no id may have (every id type's invalid value, core/common/ids.h).
  static constexpr std::uint64_t kEmpty = std::numeric_limits<std::uint64_t>::max();

  // Empties the set, with room for `expected` ids before it grows.
  void clear(std::size_t expected = 0) {
    std::size_t capacity = 64;
    while (capacity < 2 * expected) capacity *= 2;
    if (slots_.size() < capacity) slots_.resize(capacity);
    std::fill(slots_.begin(), slots_.end(), kEmpty);
    size_ = 0;
  }

  // True when `id` was not in the set (it is now). `id` must not be kEmpty.
  bool insert(std::uint64_t id) {
    if (2 * (size_ + 1) > slots_.size()) grow();
    const std::size_t mask = slots_.size() - 1;
    for (std::size_t i = slot_of(id, mask);; i = (i + 1) & mask) {
      if (slots_[i] == id) return false;
      if (slots_[i] == kEmpty) {
        slots_[i] = id;
        ++size_;
        return true;
      }
    }
  }

  bool contains(std::uint64_t id) const {
    if (slots_.empty()) return false;
    const std::size_t mask = slots_.size() - 1;
    for (std::size_t i = slot_of(id, mask);; i = (i + 1) & mask) {
      if (slots_[i] == id) return true;
      if (slots_[i] == kEmpty) return false;
    }
  }

  std::size_t size() const { return size_; }

 private:
  // Fibonacci hashing: consecutive ids (the usual case) spread over the table.
  static std::size_t slot_of(std::uint64_t id, std::size_t mask) {
    return static_cast<std::size_t>((id * 0x9E3779B97F4A7C15ull) >> 32) & mask;
  }

  void grow() {
    std::vector<std::uint64_t> old;
    old.swap(slots_);
    slots_.assign(old.empty() ? 64 : 2 * old.size(), kEmpty);
    size_ = 0;
    for (const std::uint64_t id : old)
      if (id != kEmpty) insert(id);
  }

  std::vector<std::uint64_t> slots_;
  std::size_t size_ = 0;
};

}  // namespace orbatlas
