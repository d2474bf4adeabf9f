#pragma once
// A 64-bit content hash of one database row's values, so that checkpoints can
// tell which rows changed since the last commit without keeping the rows
// themselves. Not cryptographic: two different rows of one object collide with
// probability ~2^-64, and a collision would only leave a stale row until the
// object changes again.
#include <bit>
#include <cstdint>
#include <optional>

#include "core/geometry/pose.h"

namespace orbatlas {

class RowHash {
 public:
  RowHash& add(std::uint64_t value) {
    // splitmix64's finaliser per word, folded in order (the order matters).
    std::uint64_t z = value + 0x9e3779b97f4a7c15ULL + (h_ << 6) + (h_ >> 2);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    h_ ^= z ^ (z >> 31);
    return *this;
  }
  RowHash& add(std::int64_t value) { return add(static_cast<std::uint64_t>(value)); }
  RowHash& add(int value) { return add(static_cast<std::uint64_t>(static_cast<std::int64_t>(value))); }
  // Bit patterns, so that -0.0 and 0.0 differ as they do in the stored REAL.
  RowHash& add(double value) { return add(std::bit_cast<std::uint64_t>(value)); }
  RowHash& add(float value) { return add(static_cast<std::uint64_t>(std::bit_cast<std::uint32_t>(value))); }
  // NULL and every value differ (a distinct tag first).
  RowHash& add(const std::optional<std::uint64_t>& value) {
    add(std::uint64_t{value.has_value()});
    return value ? add(*value) : *this;
  }
  RowHash& add(const Eigen::Vector3d& v) { return add(v.x()).add(v.y()).add(v.z()); }
  RowHash& add(const Pose3& pose) {
    for (const double v : {pose.q.w(), pose.q.x(), pose.q.y(), pose.q.z(), pose.t.x(), pose.t.y(), pose.t.z()}) add(v);
    return *this;
  }

  std::uint64_t value() const { return h_; }

 private:
  std::uint64_t h_ = 0x6a09e667f3bcc908ULL;
};

}  // namespace orbatlas
