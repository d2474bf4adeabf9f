#include "core/server/latency_histogram.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace orbatlas {
namespace {
constexpr std::size_t kKeptSamples = 100'000;
}

void LatencyHistogram::record(double ms) {
  std::lock_guard lock(mutex_);
  for (std::size_t i = 0; i < kBucketsMs.size(); ++i)
    if (ms <= kBucketsMs[i]) ++buckets_[i];
  ++count_;
  sum_ms_ += ms;
  if (recent_.size() < kKeptSamples) {
    recent_.push_back(ms);
  } else {
    recent_[next_] = ms;
    next_ = (next_ + 1) % kKeptSamples;
  }
}

std::string LatencyHistogram::prometheus(const std::string& name, const std::string& help) const {
  std::lock_guard lock(mutex_);
  std::ostringstream out;
  out << "# HELP " << name << " " << help << "\n# TYPE " << name << " histogram\n";
  for (std::size_t i = 0; i < kBucketsMs.size(); ++i)
    out << name << "_bucket{le=\"" << kBucketsMs[i] / 1000.0 << "\"} " << buckets_[i] << "\n";
  out << name << "_bucket{le=\"+Inf\"} " << count_ << "\n";
  out << name << "_sum " << sum_ms_ / 1000.0 << "\n" << name << "_count " << count_ << "\n";
  return out.str();
}

std::uint64_t LatencyHistogram::count() const {
  std::lock_guard lock(mutex_);
  return count_;
}

double LatencyHistogram::percentile(double p) const {
  std::vector<double> v;
  {
    std::lock_guard lock(mutex_);
    v = recent_;
  }
  if (v.empty()) return 0.0;
  const auto k = static_cast<std::size_t>(std::clamp(std::ceil(p / 100.0 * v.size()) - 1, 0.0, v.size() - 1.0));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

}  // namespace orbatlas
