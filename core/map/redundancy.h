#pragma once
// Keyframe redundancy for keyframe culling (ORB-SLAM's KeyFrameCulling), counted
// two ways: by a scan at culling time, or read in O(1) from the counts that the
// observation edits keep up to date (redundancy_tracker.h). Both give the same
// number whenever no edit is in flight.
#include "core/map/keyframe.h"
#include "core/map/redundancy_tracker.h"

namespace orbatlas {

struct RedundancyCount {
  int redundant = 0;   // map points that >= min_observers other keyframes see at level <= own + 1
  int map_points = 0;  // map points of the keyframe
};

struct RedundancyOptions {
  // The keyframe is redundant when redundant > fraction * map_points. ORB-SLAM3
  // uses 0.9 (monocular) and counts only close points for stereo; see docs/map_model.md.
  double redundant_fraction = 0.9;

  // Throws Error naming the first value out of range.
  void check() const;
};

// Scan: for every map point of the keyframe, count the other observers at the same
// or a finer level. O(points * observers) at culling time.
RedundancyCount count_redundant_scan(const KeyFrame& keyframe, int min_observers = kRedundancyMinObservers);

// Incremental: reads the keyframe's counters, O(1). Uses kRedundancyMinObservers.
RedundancyCount count_redundant_incremental(const KeyFrame& keyframe);

bool is_redundant(const RedundancyCount& count, const RedundancyOptions& options = {});

}  // namespace orbatlas
