#include "core/slam/slam_stats.h"

namespace orbatlas {

void add_atlas_counts(const Atlas& atlas, SlamStats& stats) {
  for (const auto& map : atlas.maps()) {
    if (map->keyframe_count() == 0) continue;
    ++stats.maps;
    stats.keyframes += map->keyframe_count();
    stats.mappoints += map->map_point_count();
  }
  stats.keyframe_objects = atlas.counters()->keyframes();
  stats.mappoint_objects = atlas.counters()->map_points();
}

std::size_t worker_error_total(const SlamStats& s) {
  return s.tracking_errors.errors + s.mapping.errors.errors + s.loop.errors.errors;
}

}  // namespace orbatlas
