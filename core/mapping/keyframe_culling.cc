#include "core/mapping/keyframe_culling.h"

#include <chrono>
#include <cmath>

#include "core/common/error.h"

namespace orbatlas {
namespace {

double micros_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

void KeyframeCullingOptions::check() const {
  ORBATLAS_CHECK(scheme == CullingScheme::kScan || scheme == CullingScheme::kIncremental,
                 "keyframe culling: scheme must be scan or incremental, not " << static_cast<int>(scheme));
  redundancy.check();
  ORBATLAS_CHECK(std::isfinite(max_inertial_span_s) && max_inertial_span_s >= 0.0,
                 "keyframe culling: max_inertial_span_s must be >= 0, not " << max_inertial_span_s);
  ORBATLAS_CHECK(
      std::isfinite(max_inertial_span_initialized_s) && max_inertial_span_initialized_s >= 0.0,
      "keyframe culling: max_inertial_span_initialized_s must be >= 0, not " << max_inertial_span_initialized_s);
}

const char* culling_scheme_name(CullingScheme scheme) {
  return scheme == CullingScheme::kScan ? "scan" : "incremental";
}

// The inertial chain around `kf` may lose it (KeyframeCullingOptions::max_inertial_span_s).
static bool inertial_span_allows(const Map& map, const KeyFrame& kf, const KeyframeCullingOptions& options) {
  const double limit = map.inertial_state() ? options.max_inertial_span_initialized_s : options.max_inertial_span_s;
  if (limit <= 0.0) return true;
  const auto link = kf.inertial_link();
  const auto next = kf.inertial_next();
  if (!link || !next) return !next;  // the chain's newest keyframe is kept; one outside the chain may go
  const auto previous = link->previous.lock();
  if (!previous) return true;
  return ns_to_s(next->timestamp_ns() - previous->timestamp_ns()) <= limit;
}

KeyframeCullingResult cull_redundant_keyframes(Map& map, const KeyFrame& current, std::optional<KeyframeId> origin,
                                               const KeyframeCullingOptions& options) {
  KeyframeCullingResult result;
  const bool run_scan = options.scheme == CullingScheme::kScan || options.compare_schemes;
  const bool run_incremental = options.scheme == CullingScheme::kIncremental || options.compare_schemes;
  for (const auto& edge : current.connections()) {
    if (origin && edge.keyframe == *origin) continue;
    const auto kf = map.keyframe(edge.keyframe);
    if (!kf || kf->is_bad()) continue;
    ++result.candidates;
    bool scan_says = false, incremental_says = false;
    if (run_scan) {
      const auto start = std::chrono::steady_clock::now();
      scan_says = is_redundant(count_redundant_scan(*kf), options.redundancy);
      result.scan_us += micros_since(start);
    }
    if (run_incremental) {
      const auto start = std::chrono::steady_clock::now();
      incremental_says = is_redundant(count_redundant_incremental(*kf), options.redundancy);
      result.incremental_us += micros_since(start);
    }
    if (run_scan && run_incremental && scan_says != incremental_says) ++result.disagreements;
    const bool redundant = options.scheme == CullingScheme::kScan ? scan_says : incremental_says;
    if (redundant && !inertial_span_allows(map, *kf, options)) continue;
    if (redundant && map.cull_keyframe(kf->id())) result.culled.push_back(kf->id());
  }
  return result;
}

}  // namespace orbatlas
