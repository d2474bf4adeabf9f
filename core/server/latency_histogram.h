#pragma once
// A Prometheus-style cumulative histogram of latencies in milliseconds. Thread-safe.
#include <array>
#include <cstdint>
#include <mutex>
#include <string>

namespace orbatlas {

class LatencyHistogram {
 public:
  static constexpr std::array<double, 11> kBucketsMs = {1, 2, 5, 10, 20, 30, 50, 75, 100, 250, 1000};

  void record(double ms);
  // `name`_bucket{le=...}, `name`_sum (seconds), `name`_count, with HELP/TYPE lines.
  std::string prometheus(const std::string& name, const std::string& help) const;
  std::uint64_t count() const;

 private:
  mutable std::mutex mutex_;
  std::array<std::uint64_t, kBucketsMs.size()> buckets_{};
  std::uint64_t count_ = 0;
  double sum_ms_ = 0.0;
};

}  // namespace orbatlas
