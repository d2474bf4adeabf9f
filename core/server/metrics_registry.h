#pragma once
// The Prometheus metrics of one component, kept by prometheus-cpp (Debian
// `prometheus-cpp-dev`, core library only): its counters, gauges and histograms
// are thread-safe. Each component (the service, the HTTP server, the upload
// jobs) owns one; GET /metrics (server/http) writes all of their families in
// the text exposition format, so the metric names must differ between components.
#include <memory>
#include <string>
#include <vector>

#include <prometheus/counter.h>
#include <prometheus/gauge.h>
#include <prometheus/histogram.h>
#include <prometheus/registry.h>

namespace orbatlas {

class MetricsRegistry {
 public:
  MetricsRegistry();
  MetricsRegistry(const MetricsRegistry&) = delete;
  MetricsRegistry& operator=(const MetricsRegistry&) = delete;

  // The metric `name` with `labels` (created at the first call; the same name
  // again returns the same family). References stay valid for the registry's life.
  prometheus::Counter& counter(const std::string& name, const std::string& help, const prometheus::Labels& labels = {});
  prometheus::Gauge& gauge(const std::string& name, const std::string& help, const prometheus::Labels& labels = {});
  // Bucket upper bounds in the metric's unit (seconds for latencies), increasing.
  prometheus::Histogram& histogram(const std::string& name, const std::string& help, std::vector<double> buckets);

  // The metrics as they are now (the HTTP layer writes them in the text format).
  std::vector<prometheus::MetricFamily> collect() const;

 private:
  std::shared_ptr<prometheus::Registry> registry_;
};

// Advances `counter` to `total`, a running total another part of the server keeps
// (checkpoints, merges, connections): counters only go up, so a smaller total
// changes nothing. Callers serialise their scrapes (two at once could both add).
void advance_counter_to(prometheus::Counter& counter, double total);

// Latency buckets of the server's request histograms, in seconds (1 ms .. 1 s).
std::vector<double> latency_buckets_seconds();

}  // namespace orbatlas
