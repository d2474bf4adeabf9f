#pragma once
// What a map point keeps about one keyframe observing it. The link back to the
// keyframe is weak (MapPoint -> KeyFrame never owns); the keyframe's redundancy
// counter is shared so that updating it never touches (or revives) the keyframe.
#include <atomic>
#include <cstdint>
#include <memory>

#include "core/common/ids.h"
#include "core/common/sorted_vector_map.h"

namespace orbatlas {

class KeyFrame;

struct ObserverRecord {
  std::weak_ptr<KeyFrame> keyframe;
  std::uint32_t slot = 0;  // keypoint index in the keyframe
  int level = 0;           // pyramid level of that keypoint (immutable copy)
  // Incremental redundancy (redundancy_tracker.h): the number of OTHER observers
  // whose level <= this level + 1, and the observer's count of its redundant points.
  int finer_observers = 0;
  std::shared_ptr<std::atomic<int>> redundant_counter;
};

// Ordered by keyframe id, so iteration (and the reference-keyframe choice) is
// deterministic; one vector, as tracking walks every tracked point's observers
// each frame (a tree's nodes cost a cache miss each).
using ObserverRecords = SortedVectorMap<KeyframeId, ObserverRecord>;

}  // namespace orbatlas
