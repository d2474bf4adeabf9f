#include "core/server/viewer_data.h"

#include <algorithm>

#include "core/server/live_session.h"
#include "core/server/service_error.h"

namespace orbatlas {

MapKeyframesView map_keyframes_view(const Atlas& atlas, MapId id) {
  const auto map = atlas.map(id);
  if (!map) throw_not_found("no map " + std::to_string(id));
  MapKeyframesView out;
  out.map = id;
  for (const auto& kf : map->keyframes()) {
    if (kf->is_bad()) continue;
    out.keyframes.push_back({kf->id(), kf->T_w_c(), kf->parent_id()});
    for (const KeyframeId other : kf->loop_edge_ids())
      if (kf->id() < other) out.loop_edges.emplace_back(kf->id(), other);
  }
  std::sort(out.keyframes.begin(), out.keyframes.end(), [](const auto& a, const auto& b) { return a.id < b.id; });
  std::sort(out.loop_edges.begin(), out.loop_edges.end());
  return out;
}

std::vector<float> point_buffer(const MapPointCloud& cloud, std::size_t max_points) {
  const std::size_t n = cloud.points.size();
  std::vector<float> out;
  if (n == 0 || max_points == 0) return out;
  const std::size_t step = (n + max_points - 1) / max_points;
  out.reserve(3 * (n / step + 1));
  for (std::size_t i = 0; i < n; i += step)
    for (int k = 0; k < 3; ++k) out.push_back(static_cast<float>(cloud.points[i][k]));
  return out;
}

std::vector<LiveSessionView> live_sessions_view(const AtlasService& service) {
  std::vector<LiveSessionView> out;
  for (const auto& live : service.sessions()) {
    LiveSessionView view;
    try {
      view.status = service.session_status(live->id());
    } catch (const ServiceError&) {
      continue;  // ended and forgotten meanwhile
    }
    if (view.status.state != SessionState::kActive) continue;
    if (const auto last = live->last_anchor())
      if (const auto located = service.atlas().locate_frame(*last)) {
        view.status.map = located->first;
        view.T_w_b = located->second;
      }
    out.push_back(std::move(view));
  }
  return out;
}

}  // namespace orbatlas
