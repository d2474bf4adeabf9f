#include "core/mapping/inertial_consistency.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/common/error.h"

namespace orbatlas {
namespace {

double median_of(const std::deque<double>& values) {
  if (values.empty()) return 0.0;
  std::vector<double> v(values.begin(), values.end());
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

}  // namespace

void InertialConsistencyOptions::check() const {
  ORBATLAS_CHECK(window >= 1, "inertial consistency: window must be >= 1");
  ORBATLAS_CHECK(std::isfinite(max_median_chi2) && max_median_chi2 > 0.0,
                 "inertial consistency: max_median_chi2 must be > 0, not " << max_median_chi2);
}

InertialConsistency::InertialConsistency(InertialConsistencyOptions options) : options_(options) { options_.check(); }

InertialConsistency::Verdict InertialConsistency::add(MapId map, double median_chi2) {
  if (!options_.enabled) return Verdict::kKeep;
  PerMap& m = maps_[map];
  if (m.given_up) return Verdict::kKeep;
  // A BA whose chi2 could not be evaluated counts as the worst.
  m.recent.push_back(std::isfinite(median_chi2) ? median_chi2 : 1e9);
  if (m.recent.size() > options_.window) m.recent.pop_front();
  if (m.recent.size() < options_.window || median_of(m.recent) <= options_.max_median_chi2) return Verdict::kKeep;
  m.recent.clear();
  if (m.resets >= options_.max_resets) {
    m.given_up = true;
    return Verdict::kGiveUp;
  }
  ++m.resets;
  return Verdict::kReset;
}

double InertialConsistency::recent_median(MapId map) const {
  const auto it = maps_.find(map);
  return it == maps_.end() ? 0.0 : median_of(it->second.recent);
}

bool InertialConsistency::given_up(MapId map) const {
  const auto it = maps_.find(map);
  return it != maps_.end() && it->second.given_up;
}

}  // namespace orbatlas
