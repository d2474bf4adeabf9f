#include "core/map/redundancy.h"

#include "core/common/error.h"

namespace orbatlas {

void RedundancyOptions::check() const {
  ORBATLAS_CHECK(redundant_fraction >= 0.0 && redundant_fraction <= 1.0,
                 "keyframe culling: redundant_fraction must be in [0, 1], not " << redundant_fraction);
}

RedundancyCount count_redundant_scan(const KeyFrame& keyframe, int min_observers) {
  RedundancyCount count;
  const auto slots = keyframe.slots();
  for (std::size_t i = 0; i < slots.size(); ++i) {
    const auto& mp = slots[i];
    if (!mp || mp->is_bad()) continue;
    ++count.map_points;
    const int level = keyframe.keypoint(i).level;
    if (mp->observers_up_to_level(level + 1, keyframe.id(), min_observers) >= min_observers) ++count.redundant;
  }
  return count;
}

RedundancyCount count_redundant_incremental(const KeyFrame& keyframe) {
  return {keyframe.redundant_map_point_count(), keyframe.map_point_count()};
}

bool is_redundant(const RedundancyCount& count, const RedundancyOptions& options) {
  return count.map_points > 0 && count.redundant > options.redundant_fraction * count.map_points;
}

}  // namespace orbatlas
