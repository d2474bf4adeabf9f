#pragma once
// Timing figures of a long-running worker in bounded memory: count, mean and
// max of every value, and percentiles from a fixed-size uniform sample of them
// (reservoir sampling, deterministic), exact while fewer values than the
// reservoir holds have been added. A server that runs for weeks keeps the same
// few kilobytes per figure.
#include <cstddef>
#include <cstdint>
#include <vector>

namespace orbatlas {

struct Percentiles {
  double p50 = 0.0, p95 = 0.0, p99 = 0.0, max = 0.0, mean = 0.0;
  std::size_t count = 0;
};
// Of all the values (nearest rank).
Percentiles percentiles(std::vector<double> values);

class SampleSummary {
 public:
  explicit SampleSummary(std::size_t reservoir = 1024);

  void add(double value);
  std::size_t count() const { return count_; }
  bool empty() const { return count_ == 0; }
  double mean() const { return count_ == 0 ? 0.0 : sum_ / static_cast<double>(count_); }
  double max() const { return max_; }
  // p50, p95 and p99 from the sample; count, mean and max exact.
  Percentiles percentiles() const;
  const std::vector<double>& sample() const { return sample_; }

 private:
  std::size_t capacity_;
  std::size_t count_ = 0;
  double sum_ = 0.0, max_ = 0.0;
  std::vector<double> sample_;
  std::uint64_t rng_ = 0x9E3779B97F4A7C15ULL;
};

Percentiles percentiles(const SampleSummary& summary);

}  // namespace orbatlas
