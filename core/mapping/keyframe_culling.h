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
  // Visual-inertial maps (ORB-SLAM3's rule): a keyframe of the inertial chain
  // is culled only when its predecessor and successor are at most this far apart
  // (their joined increments stay short enough to preintegrate well): before
  // the map's inertial initialisation, and once it is initialised. 0: no limit.
  double max_inertial_span_s = 0.0;
  double max_inertial_span_initialized_s = 0.0;

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
