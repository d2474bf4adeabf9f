#pragma once
// Descriptor matching utilities shared by tracking, mapping and loop closing
// (the building blocks of ORB-SLAM's ORBmatcher): best / second-best search with
// a ratio test, the rotation-consistency histogram, a brute-force matcher between
// two images and a guided matcher that searches around predicted positions.
#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <limits>
#include <vector>

#include "core/features/descriptor.h"
#include "core/features/feature_grid.h"
#include "core/features/keypoint.h"

namespace orbatlas {

// The nearest and second-nearest candidate of one descriptor (Hamming distance).
struct BestTwo {
  static constexpr std::size_t kNone = std::numeric_limits<std::size_t>::max();
  static constexpr int kNoDistance = 257;  // above any distance of 256 bits

  std::size_t index = kNone;  // candidate with the smallest distance (the first one on ties)
  int best = kNoDistance;
  int second = kNoDistance;  // smallest distance among the other candidates

  void add(std::size_t candidate, int distance);
  // ORB-SLAM's acceptance: best <= max_distance and best < ratio * second
  // (always true for the ratio when there is no second candidate).
  bool accept(int max_distance, float ratio) const;
};

// Best two of `query` among all `candidates`, or among candidates[subset[i]].
BestTwo best_two(const Descriptor& query, const std::vector<Descriptor>& candidates);
BestTwo best_two(const Descriptor& query, const std::vector<Descriptor>& candidates,
                 const std::vector<std::size_t>& subset);

// A correspondence between keypoint `a` of one image and keypoint `b` of another.
struct FeatureMatch {
  std::size_t a = 0, b = 0;
  int distance = 0;  // Hamming
};

// Rotation consistency: true matches between two views share one change of
// keypoint orientation. Differences go into 30 bins of 12 degrees (bin k is
// centred on 12k degrees); the matches outside the (up to) three most populated
// bins are the ones to reject (ORB-SLAM's ComputeThreeMaxima).
// Note: ORB-SLAM computes the bin as round(rot / 30), which uses only 13 bins of
// 30 degrees; here the 30 bins cover the circle as intended.
class RotationHistogram {
 public:
  static constexpr int kBins = 30;
  static constexpr float kBinWidthDeg = 360.0f / kBins;

  // angle_diff_deg: orientation in the first image minus orientation in the
  // second (any value, wrapped to [0, 360)); match_index: the caller's handle.
  void add(float angle_diff_deg, std::size_t match_index);
  static int bin_of(float angle_diff_deg);
  static float bin_center_deg(int bin) { return static_cast<float>(bin) * kBinWidthDeg; }

  int count(int bin) const { return static_cast<int>(bins_[static_cast<std::size_t>(bin)].size()); }
  // The most populated bin, then the second and third ones (ties: the lower bin);
  // the second and third only if they hold at least 10% of the first. -1 marks
  // "none" (all -1 when the histogram is empty).
  std::array<int, 3> top_bins() const;
  // Match indices in the other bins: those a rotation check removes.
  std::vector<std::size_t> outliers() const;
  void clear();

 private:
  std::array<std::vector<std::size_t>, kBins> bins_;
};

// Keeps the matches whose orientation change falls in the histogram's top bins
// (order preserved). angle(a) - angle(b) per match, as RotationHistogram::add.
void keep_rotation_consistent(const ImageFeatures& a, const ImageFeatures& b, std::vector<FeatureMatch>& matches);

struct BruteForceMatchOptions {
  int max_distance = kHammingHigh;
  float ratio = 0.8f;             // best < ratio * second-best over all of b
  bool check_orientation = true;  // RotationHistogram filter

  // Throws Error naming the first value out of range.
  void check() const;
};

// Every keypoint of `a` against every keypoint of `b`; the best one is kept if it
// passes the distance and ratio tests. Each keypoint of `b` ends up in at most
// one match (the one with the smallest distance; on ties the lower index of a).
// Sorted by index in a. O(|a| |b|).
std::vector<FeatureMatch> match_brute_force(const ImageFeatures& a, const ImageFeatures& b,
                                            const BruteForceMatchOptions& options = {});

struct GuidedMatchOptions {
  float radius_px = 15.0f;  // search radius around the prediction, level-0 pixels
  // The radius grows with the pyramid level of the keypoint in a: radius_px *
  // level_scale^level (1 keeps it fixed). ORB-SLAM scales by the level's scale factor.
  float level_scale = 1.2f;
  // Candidates in b must lie within this many levels of a's keypoint (-1: any level).
  int level_window = 1;
  int max_distance = kHammingHigh;
  float ratio = 0.9f;  // best < ratio * second-best among the candidates in the window
  bool check_orientation = true;

  // Throws Error naming the first value out of range.
  void check() const;
};

// For each keypoint i of `a` with a finite prediction predicted_uv_b[i] (its
// expected position in b, level-0 pixels of b; NaN to skip it), searches the
// keypoints of b within the radius via `grid_b` (built from b) and keeps the best
// one if it passes the distance and ratio tests. Each keypoint of `b` ends up in
// at most one match (the closest in descriptor space). Sorted by index in a.
// Throws Error if predicted_uv_b.size() != a.keypoints.size().
std::vector<FeatureMatch> match_guided(const ImageFeatures& a, const std::vector<Eigen::Vector2f>& predicted_uv_b,
                                       const ImageFeatures& b, const FeatureGrid& grid_b,
                                       const GuidedMatchOptions& options = {});

}  // namespace orbatlas
