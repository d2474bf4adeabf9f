// AtlasService: what the atlas holds, as the API shows it: a session's
// trajectory in its maps' frames, the maps with their sessions and bounds, a
// map's points.
#include <string>
#include <vector>

#include "core/server/atlas_service.h"
#include "core/server/service_error.h"

namespace orbatlas {

SessionTrajectory AtlasService::trajectory(SessionId id) const {
  const auto live = session(id);
  std::vector<FrameAnchor> anchors = live->anchors();
  if (!live->has_anchors()) {
    // An ended session's frames are in the database (a reader next to the
    // checkpointer's connection; WAL lets both work at once).
    std::lock_guard lock(store_mutex_);
    if (!store_) throw ServiceError(ServiceErrorKind::kUnavailable, "shutting_down", "the server is shutting down");
    anchors = store_->load_trajectory(id);
  }
  SessionTrajectory out;
  out.frames = anchors.size();
  for (const FrameAnchor& a : anchors) {
    if (const auto located = atlas_.locate_frame(a)) {
      out.poses.push_back({a.t_ns, located->second});
      out.maps.push_back(located->first);
    } else {
      ++out.unresolved;
    }
  }
  return out;
}

std::vector<MapSummary> AtlasService::maps() const {
  std::vector<MapSummary> out;
  for (const auto& map : atlas_.maps()) {
    try {
      out.push_back(this->map(map->id()));
    } catch (const ServiceError&) {
      // merged away since the list was taken
    }
  }
  return out;
}

MapSummary AtlasService::map(MapId id) const {
  const auto map = atlas_.map(id);
  if (!map) throw_not_found("no map " + std::to_string(id));
  MapSummary out;
  out.id = id;
  out.keyframes = map->keyframe_count();
  out.map_points = map->map_point_count();
  if (const auto holders = leases_.holders(id); !holders.empty() && holders.front() != kMergeWorkerLease)
    out.live_session = holders.front();
  out.sessions = sessions_.in_map(id);
  out.writable = !ownership_ || ownership_->owns(id);
  const auto points = map->map_points();
  if (!points.empty()) {
    MapSummary::Bounds bounds{Eigen::Vector3d::Constant(1e300), Eigen::Vector3d::Constant(-1e300)};
    for (const auto& p : points) {
      bounds.min = bounds.min.cwiseMin(p->p_w());
      bounds.max = bounds.max.cwiseMax(p->p_w());
    }
    out.bounds_m = bounds;
  }
  return out;
}

MapPointCloud AtlasService::map_points(MapId id) const {
  const auto map = atlas_.map(id);
  if (!map) throw_not_found("no map " + std::to_string(id));
  MapPointCloud out;
  out.map = id;
  for (const auto& p : map->map_points())
    if (!p->is_bad()) out.points.push_back(p->p_w());
  return out;
}

}  // namespace orbatlas
