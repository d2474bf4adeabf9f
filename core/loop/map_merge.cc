#include "core/loop/map_merge.h"

#include <chrono>
#include <cmath>
#include <unordered_map>
#include <unordered_set>

#include "core/common/error.h"
#include "core/geometry/yaw_only.h"
#include "core/common/stopwatch.h"
#include "core/mapping/fusion.h"

namespace orbatlas {
namespace {

// `current` becomes the root of its spanning tree (the path to the old root is
// reversed), then a child of `matched`.
void join_spanning_trees(const std::shared_ptr<KeyFrame>& current, const std::shared_ptr<KeyFrame>& matched) {
  std::vector<std::shared_ptr<KeyFrame>> path{current};
  std::unordered_set<KeyframeId> seen{current->id()};
  while (auto parent = path.back()->parent()) {
    if (!seen.insert(parent->id()).second) break;  // a cycle would be a bug elsewhere; do not loop
    path.push_back(std::move(parent));
  }
  for (std::size_t i = path.size() - 1; i >= 1; --i) path[i]->set_parent(path[i - 1]);
  current->set_parent(matched);
}

}  // namespace

void MapMergeOptions::check() const {
  ORBATLAS_CHECK(std::isfinite(fusion_th) && fusion_th >= 0.0f,
                 "map merge: fusion_th must be a finite value >= 0, not " << fusion_th);
}

bool merge_keeps_scale(const Map& source, const Map& target) { return !source.metric_scale() || target.metric_scale(); }

bool merges_in_sim3(const Map& source, bool single_camera, std::size_t settled_refinements) {
  if (!single_camera) return false;
  if (!source.metric_scale()) return true;
  if (source.measured_depth()) return false;
  const auto inertial = source.inertial_state();
  return inertial && inertial->refinements < settled_refinements;
}

MapMergeStats merge_maps(Atlas& atlas, const PlaceMatch& match, const FrameCamera& cam,
                         const MapMergeOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  options.check();
  const auto& current = match.current;
  const auto& matched = match.matched;
  ORBATLAS_CHECK(current && matched, "map merge needs both keyframes");
  ORBATLAS_CHECK(!match.same_map(), "map merge: keyframes " << current->id() << " and " << matched->id()
                                                            << " are in one map (a loop, not a merge)");
  const auto whole = atlas.lock_maps_exclusive();
  const auto source = atlas.map(current->map_id());
  const auto target = atlas.map(matched->map_id());
  ORBATLAS_CHECK(source && target,
                 "map merge: map " << current->map_id() << " or " << matched->map_id() << " is not in the atlas");
  MapMergeStats stats;
  stats.source = source->id();
  stats.target = target->id();

  // 1. Move the source map into the target's world. The match says where the
  // current camera is in the target's world.
  const Pose3 T_ws_c = current->T_w_c();
  const Sim3 S_wt_ws = match.S_c_w_corrected.inverse() * Sim3(T_ws_c.inverse());
  if (match.scale_free) {
    // A map of free scale (monocular), or a monocular-inertial one whose
    // scale has not settled, takes the target's: scaled about its origin first
    // (lengths, and with its keyframes' units the poses kept relative to them;
    // IMU velocities), then moved rigidly.
    ORBATLAS_CHECK(!source->metric_scale() || target->metric_scale(),
                   "map merge: map " << source->id() << " is metric and map " << target->id()
                                     << " is not; a merge cannot take its scale");
    stats.scale = S_wt_ws.s;
    source->rescale(S_wt_ws.s);
  }
  Pose3 T_wt_ws(S_wt_ws.q, S_wt_ws.t);
  if (const auto source_imu = source->inertial_state(), target_imu = target->inertial_state();
      source_imu && target_imu) {
    // Both worlds know their gravity: they differ by a turn about it and a
    // move (the current camera, where the rescale above put it, lands where
    // the match puts it); the source's gravity lands on the target's.
    T_wt_ws = yaw_only_transform(T_wt_ws, stats.scale * T_ws_c.t, target_imu->up(), source_imu->up());
    stats.four_dof = true;
  }
  const Map::AbsorbCounts moved = target->absorb(*source, T_wt_ws);
  atlas.remove_map(source->id());
  stats.keyframes_moved = moved.keyframes;
  stats.points_moved = moved.map_points;

  // 2. One spanning tree.
  join_spanning_trees(current, matched);

  // 3. Fuse the matched window's points into the current keyframe's group.
  std::vector<std::shared_ptr<KeyFrame>> group{current};
  for (auto& kf : current->best_covisibles(20)) group.push_back(std::move(kf));
  std::unordered_map<KeyframeId, std::unordered_set<KeyframeId>> previous;
  for (const auto& kf : group)
    for (const auto& edge : kf->connections()) previous[kf->id()].insert(edge.keyframe);
  for (const auto& kf : group) {
    if (kf->is_bad()) continue;
    const FusionStats f = fuse_into_keyframe(*target, kf, match.window_points, cam, options.fusion_th);
    stats.observations_fused += static_cast<std::size_t>(f.added);
    stats.points_fused += static_cast<std::size_t>(f.merged);
  }
  for (const auto& kf : group) {
    if (kf->is_bad()) continue;
    kf->update_connections();
    for (const auto& edge : kf->connections())
      if (!previous[kf->id()].count(edge.keyframe)) ++stats.new_links;
  }
  current->add_loop_edge(matched);
  stats.ms = ms_since(start);
  return stats;
}

}  // namespace orbatlas
