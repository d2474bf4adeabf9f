#pragma once
// Keyframe culling (ORB-SLAM's KeyFrameCulling): a covisible keyframe of the one
// just processed is culled when more than 90% of its map points are seen by at
// least three other keyframes at the same or a finer scale. The redundancy is
// counted by a scan or read from the incremental counts (core/map/redundancy.h);
// a setting chooses, and both can be run side by side to compare decisions.
// Divergence from ORB-SLAM3: for stereo keyframes it counts only close points;
// here every point counts, for both schemes (see docs/mapping.md).
#include <memory>
#include <optional>
#include <vector>

#include "core/map/map.h"
#include "core/map/redundancy.h"

namespace orbatlas {

enum class CullingScheme { kScan, kIncremental };
const char* culling_scheme_name(CullingScheme scheme);

struct KeyframeCullingOptions {
  CullingScheme scheme = CullingScheme::kIncremental;
  bool compare_schemes = false;  // also run the other scheme and count disagreements
  RedundancyOptions redundancy;

  // Throws Error naming the first value out of range.
  void check() const;
};

struct KeyframeCullingResult {
  std::vector<KeyframeId> culled;
  int candidates = 0;
  int disagreements = 0;        // with compare_schemes: decisions where the schemes differ
  double scan_us = 0.0;         // time spent counting by scan (when run)
  double incremental_us = 0.0;  // time spent reading the incremental counts (when run)
};

// Candidates: the covisible keyframes of `current`, never `origin` (the map's
// first keyframe).
KeyframeCullingResult cull_redundant_keyframes(Map& map, const KeyFrame& current, std::optional<KeyframeId> origin,
                                               const KeyframeCullingOptions& options);

}  // namespace orbatlas
