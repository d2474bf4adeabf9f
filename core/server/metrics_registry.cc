#include "core/server/metrics_registry.h"

namespace orbatlas {

MetricsRegistry::MetricsRegistry() : registry_(std::make_shared<prometheus::Registry>()) {}

prometheus::Counter& MetricsRegistry::counter(const std::string& name, const std::string& help,
                                              const prometheus::Labels& labels) {
  return prometheus::BuildCounter().Name(name).Help(help).Register(*registry_).Add(labels);
}

prometheus::Gauge& MetricsRegistry::gauge(const std::string& name, const std::string& help,
                                          const prometheus::Labels& labels) {
  return prometheus::BuildGauge().Name(name).Help(help).Register(*registry_).Add(labels);
}

prometheus::Histogram& MetricsRegistry::histogram(const std::string& name, const std::string& help,
                                                  std::vector<double> buckets) {
  return prometheus::BuildHistogram().Name(name).Help(help).Register(*registry_).Add({}, std::move(buckets));
}

std::vector<prometheus::MetricFamily> MetricsRegistry::collect() const { return registry_->Collect(); }

void advance_counter_to(prometheus::Counter& counter, double total) {
  if (total > counter.Value()) counter.Increment(total - counter.Value());
}

std::vector<double> latency_buckets_seconds() {
  return {0.001, 0.002, 0.005, 0.010, 0.020, 0.030, 0.050, 0.075, 0.100, 0.250, 1.0};
}

}  // namespace orbatlas
