#include "core/server/latency_histogram.h"

#include <sstream>

namespace orbatlas {
void LatencyHistogram::record(double ms) {
  std::lock_guard lock(mutex_);
  for (std::size_t i = 0; i < kBucketsMs.size(); ++i)
    if (ms <= kBucketsMs[i]) ++buckets_[i];
  ++count_;
  sum_ms_ += ms;
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

}  // namespace orbatlas
