#pragma once
// Keyframe content for the map model tests: `slots` keypoints, the first ones
// at the given pyramid levels, and nothing else.
#include <cstddef>
#include <vector>

#include "core/map/keyframe_data.h"

namespace orbatlas::test {

inline KeyFrameData keyframe_data(std::size_t slots, const std::vector<int>& levels = {}) {
  KeyFrameData data;
  data.features.keypoints.resize(slots);
  for (std::size_t i = 0; i < slots && i < levels.size(); ++i) data.features.keypoints[i].level = levels[i];
  return data;
}

}  // namespace orbatlas::test
