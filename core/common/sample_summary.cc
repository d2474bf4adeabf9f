#include "core/common/sample_summary.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace orbatlas {

Percentiles percentiles(std::vector<double> values) {
  Percentiles p;
  p.count = values.size();
  if (values.empty()) return p;
  std::sort(values.begin(), values.end());
  auto at = [&](double q) {
    const std::size_t i = static_cast<std::size_t>(std::lround(q * static_cast<double>(values.size() - 1)));
    return values[std::min(i, values.size() - 1)];
  };
  p.p50 = at(0.50);
  p.p95 = at(0.95);
  p.p99 = at(0.99);
  p.max = values.back();
  p.mean = std::accumulate(values.begin(), values.end(), 0.0) / static_cast<double>(values.size());
  return p;
}

SampleSummary::SampleSummary(std::size_t reservoir) : capacity_(std::max<std::size_t>(1, reservoir)) {}

void SampleSummary::add(double value) {
  ++count_;
  sum_ += value;
  max_ = count_ == 1 ? value : std::max(max_, value);
  if (sample_.size() < capacity_) {
    sample_.push_back(value);
    return;
  }
  // Algorithm R: the new value replaces a random slot with probability capacity / count.
  rng_ ^= rng_ << 13;
  rng_ ^= rng_ >> 7;
  rng_ ^= rng_ << 17;
  const std::uint64_t slot = rng_ % count_;
  if (slot < capacity_) sample_[slot] = value;
}

Percentiles SampleSummary::percentiles() const {
  Percentiles p = orbatlas::percentiles(sample_);
  p.count = count_;
  p.mean = mean();
  p.max = max_;
  return p;
}

Percentiles percentiles(const SampleSummary& summary) { return summary.percentiles(); }

}  // namespace orbatlas
