#include "core/tracking/monocular_initializer.h"

#include <cmath>
#include <limits>

#include "core/common/error.h"
#include "core/features/matching.h"

namespace orbatlas {

void MonocularInitializerOptions::check() const {
  ORBATLAS_CHECK(min_keypoints >= 8, "monocular initialisation: min_keypoints must be >= 8, not " << min_keypoints);
  ORBATLAS_CHECK(min_matches >= 8, "monocular initialisation: min_matches must be >= 8, not " << min_matches);
  ORBATLAS_CHECK(std::isfinite(search_radius_px) && search_radius_px > 0.0f,
                 "monocular initialisation: search_radius_px must be > 0, not " << search_radius_px);
  ORBATLAS_CHECK(min_points >= 8, "monocular initialisation: min_points must be >= 8, not " << min_points);
  ORBATLAS_CHECK(std::isfinite(max_reference_age_s) && max_reference_age_s > 0.0,
                 "monocular initialisation: max_reference_age_s must be > 0, not " << max_reference_age_s);
  two_view.check();
}

MonocularInitializer::MonocularInitializer(MonocularInitializerOptions options, double focal_px)
    : options_(std::move(options)) {
  options_.two_view.focal_px = focal_px;
  options_.check();
}

void MonocularInitializer::reset() {
  reference_.reset();
  predicted_.clear();
}

void MonocularInitializer::take_as_reference(const Frame& frame) {
  reference_ = frame;
  reference_->map_points.assign(frame.size(), nullptr);
  reference_->outlier.assign(frame.size(), false);
  // Only the finest level is matched (ORB-SLAM's SearchForInitialization):
  // the coarse levels' keypoints are few and poorly localised.
  const float nan = std::numeric_limits<float>::quiet_NaN();
  predicted_.assign(frame.size(), Eigen::Vector2f(nan, nan));
  for (std::size_t i = 0; i < frame.size(); ++i)
    if (frame.features.keypoints[i].level == 0) predicted_[i] = frame.features.keypoints[i].uv;
}

std::optional<MonocularStart> MonocularInitializer::offer(const Frame& frame) {
  if (static_cast<int>(frame.size()) < options_.min_keypoints) {
    reset();
    last_failure_ = "too few keypoints (" + std::to_string(frame.size()) + ")";
    return std::nullopt;
  }
  if (!reference_ || ns_to_s(frame.t_ns - reference_->t_ns) > options_.max_reference_age_s) {
    take_as_reference(frame);
    return std::nullopt;
  }
  GuidedMatchOptions search;
  search.radius_px = options_.search_radius_px;
  search.level_scale = 1.0f;
  search.level_window = 0;
  search.max_distance = kHammingLow;
  search.ratio = 0.9f;
  const auto matches = match_guided(reference_->features, predicted_, frame.features, frame.grid, search);
  if (static_cast<int>(matches.size()) < options_.min_matches) {
    last_failure_ = "too few matches with the reference (" + std::to_string(matches.size()) + ")";
    take_as_reference(frame);
    return std::nullopt;
  }
  // The next attempt searches around these matches.
  for (const auto& m : matches) predicted_[m.a] = frame.features.keypoints[m.b].uv;

  std::vector<Eigen::Vector2d> x1, x2;
  x1.reserve(matches.size());
  x2.reserve(matches.size());
  for (const auto& m : matches) {
    const Eigen::Vector3d& b1 = reference_->features.keypoints[m.a].bearing;
    const Eigen::Vector3d& b2 = frame.features.keypoints[m.b].bearing;
    x1.push_back(b1.head<2>() / b1.z());
    x2.push_back(b2.head<2>() / b2.z());
  }
  ++attempts_;
  const TwoViewResult r = reconstruct_two_views(x1, x2, options_.two_view);
  if (!r.success || r.triangulated_count < options_.min_points) {
    last_failure_ =
        r.success ? "too few points triangulated (" + std::to_string(r.triangulated_count) + ")" : r.failure;
    return std::nullopt;  // the same reference, with the next frame
  }
  MonocularStart start;
  start.T_c2_c1 = r.T_c2_c1;
  start.model = r.model;
  start.parallax_deg = r.parallax_deg;
  for (std::size_t k = 0; k < matches.size(); ++k)
    if (r.triangulated[k]) start.points.push_back({matches[k].a, matches[k].b, r.points_c1[k]});
  start.reference = std::move(*reference_);
  reset();
  return start;
}

}  // namespace orbatlas
