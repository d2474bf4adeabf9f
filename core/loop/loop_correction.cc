#include "core/loop/loop_correction.h"

#include <algorithm>
#include <chrono>
#include <set>
#include <unordered_map>
#include <unordered_set>

#include "core/common/error.h"
#include "core/common/stopwatch.h"
#include "core/geometry/sim3_correction.h"
#include "core/map/map_point_update.h"
#include "core/mapping/fusion.h"

namespace orbatlas {
namespace {

void set_camera_pose(KeyFrame& kf, const Pose3& T_c_w) { kf.set_T_w_b(T_c_w.inverse() * kf.T_b_c().inverse()); }

}  // namespace

LoopCorrectionStats correct_loop(Map& map, const PlaceMatch& loop, const FrameCamera& cam,
                                 const LoopCorrectionOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  LoopCorrectionStats stats;
  const auto& current = loop.current;
  const auto& matched = loop.matched;
  ORBATLAS_CHECK(current && matched, "loop correction needs both keyframes");
  ORBATLAS_CHECK(current->map_id() == map.id() && matched->map_id() == map.id(),
                 "loop correction: keyframes " << current->id() << " and " << matched->id() << " are not both in map "
                                               << map.id());
  if (current->is_bad() || matched->is_bad()) return stats;

  // 1. The group and its corrected poses (world -> camera).
  std::vector<std::shared_ptr<KeyFrame>> group{current};
  for (const auto& edge : current->connections())
    if (auto kf = map.keyframe(edge.keyframe); kf && !kf->is_bad()) group.push_back(std::move(kf));
  const Pose3 T_a_w_old = current->T_w_c().inverse();
  const Sim3 S_a_w_new(loop.T_c_w_corrected);
  std::unordered_map<KeyframeId, Pose3> old_T_c_w;
  std::unordered_map<KeyframeId, Sim3> corrected;
  for (const auto& kf : group) {
    old_T_c_w[kf->id()] = kf->T_w_c().inverse();
    corrected[kf->id()] = propagate_correction(old_T_c_w[kf->id()], T_a_w_old, S_a_w_new);
  }
  {
    const Pose3 T_w_c_new = rigid_pose_c_w(S_a_w_new).inverse();
    const Pose3 T_w_c_old = T_a_w_old.inverse();
    stats.correction_m = translation_distance(T_w_c_old, T_w_c_new);
    stats.correction_deg = rotation_distance(T_w_c_old, T_w_c_new) * 180.0 / M_PI;
  }

  std::unordered_map<MapPointId, KeyframeId> corrected_by;
  std::vector<std::shared_ptr<MapPoint>> moved;
  for (const auto& kf : group) {
    for (const auto& mp : kf->map_points()) {
      if (mp->is_bad() || !corrected_by.emplace(mp->id(), kf->id()).second) continue;
      mp->set_p_w(correct_point(old_T_c_w[kf->id()], corrected[kf->id()], mp->p_w()));
      moved.push_back(mp);
    }
  }
  for (const auto& kf : group) set_camera_pose(*kf, rigid_pose_c_w(corrected[kf->id()]));
  for (const auto& mp : moved) update_normal_and_distances(*mp, cam.pyramid);
  stats.group_keyframes = group.size();
  stats.corrected_points = moved.size();

  // 2. Fuse the window's points into the group; new links cross the loop.
  std::unordered_set<KeyframeId> group_ids;
  for (const auto& kf : group) group_ids.insert(kf->id());
  std::unordered_map<KeyframeId, std::unordered_set<KeyframeId>> previous;
  for (const auto& kf : group)
    for (const auto& edge : kf->connections()) previous[kf->id()].insert(edge.keyframe);
  for (const auto& kf : group) {
    const FusionStats f = fuse_into_keyframe(map, kf, loop.window_points, cam, options.fusion_th);
    stats.observations_fused += static_cast<std::size_t>(f.added);
    stats.points_merged += static_cast<std::size_t>(f.merged);
  }
  std::unordered_map<KeyframeId, std::vector<KeyframeId>> loop_links;
  for (const auto& kf : group) {
    kf->update_connections();
    for (const auto& edge : kf->connections()) {
      if (previous[kf->id()].count(edge.keyframe) || group_ids.count(edge.keyframe)) continue;
      loop_links[kf->id()].push_back(edge.keyframe);
      ++stats.new_links;
    }
  }

  // 3. Essential graph over the whole map.
  const auto keyframes = map.keyframes();  // by id: the first is the map's origin
  std::vector<PoseGraphNode> nodes;
  std::unordered_map<KeyframeId, Sim3> initial, before;  // graph start / pre-loop (non-corrected)
  for (const auto& kf : keyframes) {
    if (kf->is_bad()) continue;
    const auto it = corrected.find(kf->id());
    const Pose3 T_c_w_now = kf->T_w_c().inverse();
    initial[kf->id()] = it != corrected.end() ? it->second : Sim3(T_c_w_now);
    before[kf->id()] = it != corrected.end() ? Sim3(old_T_c_w[kf->id()]) : Sim3(T_c_w_now);
    nodes.push_back({kf->id(), initial[kf->id()], nodes.empty()});
  }
  std::vector<PoseGraphEdge> edges;
  std::set<std::pair<KeyframeId, KeyframeId>> linked;
  auto add_edge = [&](KeyframeId i, KeyframeId j, const std::unordered_map<KeyframeId, Sim3>& poses,
                      PoseGraphEdgeKind kind) {
    if (i == j || !poses.count(i) || !poses.count(j)) return;
    if (!linked.insert({std::min(i, j), std::max(i, j)}).second) return;
    edges.push_back({i, j, poses.at(i) * poses.at(j).inverse(), 1.0, kind});
  };
  // Loop links: measured with the corrected poses (they are what the loop says).
  add_edge(current->id(), matched->id(), initial, PoseGraphEdgeKind::kLoop);
  for (const auto& [i, links] : loop_links) {
    const auto kf = map.keyframe(i);
    if (!kf) continue;
    for (const KeyframeId j : links)
      if (kf->weight(j) >= options.strong_covisibility) add_edge(i, j, initial, PoseGraphEdgeKind::kLoop);
  }
  // The rest: measured with the poses from before the loop (the drifted odometry).
  for (const auto& kf : keyframes) {
    if (kf->is_bad()) continue;
    if (const auto parent = kf->parent(); parent && !parent->is_bad())
      add_edge(kf->id(), parent->id(), before, PoseGraphEdgeKind::kSpanningTree);
    for (const KeyframeId j : kf->loop_edge_ids()) add_edge(kf->id(), j, before, PoseGraphEdgeKind::kLoop);
    for (const auto& edge : kf->connections()) {
      if (edge.weight < options.strong_covisibility) break;  // weight descending
      add_edge(kf->id(), edge.keyframe, before, PoseGraphEdgeKind::kCovisibility);
    }
  }
  EssentialGraphOptions graph_options = options.graph;
  graph_options.fix_scale = true;  // stereo maps have metric scale
  const auto graph_start = std::chrono::steady_clock::now();
  const EssentialGraphResult result = optimize_essential_graph(nodes, edges, graph_options);
  stats.graph_ms = ms_since(graph_start);
  stats.graph_nodes = nodes.size();
  stats.graph_edges = edges.size();

  std::unordered_map<KeyframeId, Sim3> optimised;
  for (const auto& node : result.nodes) optimised[node.id] = node.S_n_w;
  for (const auto& kf : keyframes)
    if (const auto it = optimised.find(kf->id()); it != optimised.end() && !kf->is_bad())
      set_camera_pose(*kf, rigid_pose_c_w(it->second));
  // Points follow the keyframe that corrected them, else their reference keyframe.
  for (const auto& mp : map.map_points()) {
    if (mp->is_bad()) continue;
    KeyframeId ref = 0;
    if (const auto it = corrected_by.find(mp->id()); it != corrected_by.end()) {
      ref = it->second;
    } else if (const auto r = mp->reference_keyframe_id()) {
      ref = *r;
    } else {
      continue;
    }
    const auto from = initial.find(ref);
    const auto to = optimised.find(ref);
    if (from == initial.end() || to == optimised.end()) continue;
    mp->set_p_w(to->second.inverse() * (from->second * mp->p_w()));
    update_normal_and_distances(*mp, cam.pyramid);
  }

  current->add_loop_edge(matched);
  stats.total_ms = ms_since(start);
  return stats;
}

}  // namespace orbatlas
