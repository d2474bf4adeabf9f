#pragma once
// What the map viewer (viewer/, docs/viewer.md) reads besides the API's maps,
// sessions and merges: a map's keyframes (poses, spanning tree, loop edges),
// its points as a compact buffer with a level-of-detail cap, and every live
// session's last pose. Read-only views of the atlas; no HTTP here.
#include <cstddef>
#include <optional>
#include <utility>
#include <vector>

#include "core/common/ids.h"
#include "core/geometry/pose.h"
#include "core/server/atlas_service.h"
#include "core/server/service_results.h"

namespace orbatlas {

// GET /v1/maps/{id}/keyframes.
struct MapKeyframesView {
  struct Keyframe {
    KeyframeId id = 0;
    Pose3 T_w_c;                       // the (left) camera in the map's frame
    std::optional<KeyframeId> parent;  // spanning tree (none for a root, or a parent culled since)
  };
  MapId map = 0;
  std::vector<Keyframe> keyframes;
  std::vector<std::pair<KeyframeId, KeyframeId>> loop_edges;  // each once, smaller id first
};
MapKeyframesView map_keyframes_view(const Atlas& atlas, MapId id);  // ServiceError not_found

// GET /v1/maps/{id}/points.bin: x, y, z of at most `max_points` of the cloud's
// points (every k-th, k as small as the cap allows; all when they fit).
std::vector<float> point_buffer(const MapPointCloud& cloud, std::size_t max_points);

// GET /v1/live: each live session's status and where its last tracked frame is now.
struct LiveSessionView {
  SessionStatus status;
  std::optional<Pose3> T_w_b;  // in status.map; none before a tracked frame
};
std::vector<LiveSessionView> live_sessions_view(const AtlasService& service);

}  // namespace orbatlas
