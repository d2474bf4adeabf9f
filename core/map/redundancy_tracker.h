#pragma once
// Incremental keyframe-redundancy counting (thesis ch. 5), kept exact while
// observations come and go. A map point of keyframe k (seen at level L_k) is
// redundant for k when at least kRedundancyMinObservers OTHER keyframes observe it
// at level <= L_k + 1. Each ObserverRecord carries that number of other observers
// (finer_observers); each keyframe an atomic count of its redundant points.
// Both functions run with the map point's mutex held; they cost O(observers).
#include "core/map/observer_record.h"

namespace orbatlas {

inline constexpr int kRedundancyMinObservers = 3;  // ORB-SLAM's thObs

// Adds `record` for keyframe `id` (must be absent): sets its finer_observers,
// raises the other observers' counts it contributes to, and bumps the redundant
// counter of every observer whose count reaches the threshold (including the new one).
void track_attach(ObserverRecords& records, KeyframeId id, ObserverRecord record);

// Removes keyframe `id` (no-op if absent) and undoes its contributions.
void track_detach(ObserverRecords& records, KeyframeId id);

}  // namespace orbatlas
