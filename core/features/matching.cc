#include "core/features/matching.h"

#include <cmath>

#include "core/common/error.h"

namespace orbatlas {
namespace {

// One match per keypoint of b: the smallest distance wins, the earlier match on
// ties. `matches` is sorted by a and stays so.
void keep_unique_in_b(std::size_t b_count, std::vector<FeatureMatch>& matches) {
  constexpr std::size_t kFree = BestTwo::kNone;
  std::vector<std::size_t> owner(b_count, kFree);  // match index per keypoint of b
  std::vector<bool> dropped(matches.size(), false);
  for (std::size_t m = 0; m < matches.size(); ++m) {
    std::size_t& o = owner[matches[m].b];
    if (o == kFree) {
      o = m;
    } else if (matches[m].distance < matches[o].distance) {
      dropped[o] = true;
      o = m;
    } else {
      dropped[m] = true;
    }
  }
  std::size_t kept = 0;
  for (std::size_t m = 0; m < matches.size(); ++m)
    if (!dropped[m]) matches[kept++] = matches[m];
  matches.resize(kept);
}

}  // namespace

void BruteForceMatchOptions::check() const {
  ORBATLAS_CHECK(max_distance >= 0, "matching: max_distance must be >= 0, not " << max_distance);
  ORBATLAS_CHECK(ratio >= 0.0f && ratio <= 1.0f, "matching: ratio must be in [0, 1], not " << ratio);
}

void GuidedMatchOptions::check() const {
  ORBATLAS_CHECK(std::isfinite(radius_px) && radius_px >= 0.0f,
                 "guided matching: radius_px must be a finite value >= 0, not " << radius_px);
  ORBATLAS_CHECK(std::isfinite(level_scale) && level_scale > 0.0f,
                 "guided matching: level_scale must be a finite value > 0, not " << level_scale);
  ORBATLAS_CHECK(level_window >= -1,
                 "guided matching: level_window must be >= -1 (-1: any level), not " << level_window);
  ORBATLAS_CHECK(max_distance >= 0, "guided matching: max_distance must be >= 0, not " << max_distance);
  ORBATLAS_CHECK(ratio >= 0.0f && ratio <= 1.0f, "guided matching: ratio must be in [0, 1], not " << ratio);
}

void BestTwo::add(std::size_t candidate, int distance) {
  if (distance < best) {
    second = best;
    best = distance;
    index = candidate;
  } else if (distance < second) {
    second = distance;
  }
}

bool BestTwo::accept(int max_distance, float ratio) const {
  if (index == kNone || best > max_distance) return false;
  return second == kNoDistance || static_cast<float>(best) < ratio * static_cast<float>(second);
}

BestTwo best_two(const Descriptor& query, const std::vector<Descriptor>& candidates) {
  BestTwo r;
  for (std::size_t i = 0; i < candidates.size(); ++i) r.add(i, hamming(query, candidates[i]));
  return r;
}

BestTwo best_two(const Descriptor& query, const std::vector<Descriptor>& candidates,
                 const std::vector<std::size_t>& subset) {
  BestTwo r;
  for (const std::size_t i : subset) r.add(i, hamming(query, candidates[i]));
  return r;
}

int RotationHistogram::bin_of(float angle_diff_deg) {
  float rot = std::fmod(angle_diff_deg, 360.0f);
  if (rot < 0.0f) rot += 360.0f;
  const long bin = std::lround(rot / kBinWidthDeg);
  return bin >= kBins ? 0 : static_cast<int>(bin);
}

void RotationHistogram::add(float angle_diff_deg, std::size_t match_index) {
  bins_[static_cast<std::size_t>(bin_of(angle_diff_deg))].push_back(match_index);
}

std::array<int, 3> RotationHistogram::top_bins() const {
  std::array<int, 3> top = {-1, -1, -1};
  std::array<std::size_t, 3> size = {0, 0, 0};
  for (int i = 0; i < kBins; ++i) {
    const std::size_t s = bins_[static_cast<std::size_t>(i)].size();
    if (s > size[0]) {
      size = {s, size[0], size[1]};
      top = {i, top[0], top[1]};
    } else if (s > size[1]) {
      size = {size[0], s, size[1]};
      top = {top[0], i, top[1]};
    } else if (s > size[2]) {
      size[2] = s;
      top[2] = i;
    }
  }
  const float tenth = 0.1f * static_cast<float>(size[0]);
  if (static_cast<float>(size[1]) < tenth) {
    top[1] = top[2] = -1;
  } else if (static_cast<float>(size[2]) < tenth) {
    top[2] = -1;
  }
  return top;
}

std::vector<std::size_t> RotationHistogram::outliers() const {
  const std::array<int, 3> top = top_bins();
  std::vector<std::size_t> out;
  for (int i = 0; i < kBins; ++i) {
    if (i == top[0] || i == top[1] || i == top[2]) continue;
    const auto& bin = bins_[static_cast<std::size_t>(i)];
    out.insert(out.end(), bin.begin(), bin.end());
  }
  return out;
}

void RotationHistogram::clear() {
  for (auto& bin : bins_) bin.clear();
}

void keep_rotation_consistent(const ImageFeatures& a, const ImageFeatures& b, std::vector<FeatureMatch>& matches) {
  RotationHistogram histogram;
  for (std::size_t m = 0; m < matches.size(); ++m)
    histogram.add(a.keypoints[matches[m].a].angle_deg - b.keypoints[matches[m].b].angle_deg, m);
  std::vector<bool> drop(matches.size(), false);
  for (const std::size_t m : histogram.outliers()) drop[m] = true;
  std::size_t kept = 0;
  for (std::size_t m = 0; m < matches.size(); ++m)
    if (!drop[m]) matches[kept++] = matches[m];
  matches.resize(kept);
}

std::vector<FeatureMatch> match_brute_force(const ImageFeatures& a, const ImageFeatures& b,
                                            const BruteForceMatchOptions& options) {
  ORBATLAS_CHECK(a.descriptors.size() == a.keypoints.size() && b.descriptors.size() == b.keypoints.size(),
                 "match_brute_force: keypoints and descriptors differ in number");
  std::vector<FeatureMatch> matches;
  for (std::size_t i = 0; i < a.descriptors.size(); ++i) {
    const BestTwo r = best_two(a.descriptors[i], b.descriptors);
    if (r.accept(options.max_distance, options.ratio)) matches.push_back({i, r.index, r.best});
  }
  keep_unique_in_b(b.keypoints.size(), matches);
  if (options.check_orientation) keep_rotation_consistent(a, b, matches);
  return matches;
}

std::vector<FeatureMatch> match_guided(const ImageFeatures& a, const std::vector<Eigen::Vector2f>& predicted_uv_b,
                                       const ImageFeatures& b, const FeatureGrid& grid_b,
                                       const GuidedMatchOptions& options) {
  ORBATLAS_CHECK(predicted_uv_b.size() == a.keypoints.size(), "match_guided: " << predicted_uv_b.size()
                                                                               << " predictions for "
                                                                               << a.keypoints.size() << " keypoints");
  ORBATLAS_CHECK(a.descriptors.size() == a.keypoints.size() && b.descriptors.size() == b.keypoints.size(),
                 "match_guided: keypoints and descriptors differ in number");
  ORBATLAS_CHECK(grid_b.size() <= b.keypoints.size(), "match_guided: the grid was not built from b");
  std::vector<FeatureMatch> matches;
  std::vector<std::size_t> candidates;
  for (std::size_t i = 0; i < a.keypoints.size(); ++i) {
    const Eigen::Vector2f& uv = predicted_uv_b[i];
    if (!std::isfinite(uv.x()) || !std::isfinite(uv.y())) continue;
    const int level = a.keypoints[i].level;
    const float radius = options.radius_px * std::pow(options.level_scale, static_cast<float>(level));
    const int min_level = options.level_window >= 0 ? std::max(0, level - options.level_window) : -1;
    const int max_level = options.level_window >= 0 ? level + options.level_window : -1;
    grid_b.in_radius(uv, radius, min_level, max_level, candidates);
    const BestTwo r = best_two(a.descriptors[i], b.descriptors, candidates);
    if (r.accept(options.max_distance, options.ratio)) matches.push_back({i, r.index, r.best});
  }
  keep_unique_in_b(b.keypoints.size(), matches);
  if (options.check_orientation) keep_rotation_consistent(a, b, matches);
  return matches;
}

}  // namespace orbatlas
