#include "core/loop/loop_correction.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <set>
#include <unordered_map>
#include <unordered_set>

#include "core/common/error.h"
#include "core/common/stopwatch.h"
#include "core/geometry/sim3_correction.h"
#include "core/geometry/yaw_only.h"
#include "core/map/map_point_update.h"
#include "core/mapping/fusion.h"

namespace orbatlas {
namespace {

void set_camera_pose(KeyFrame& kf, const Pose3& T_c_w) { kf.set_T_w_b(T_c_w.inverse() * kf.T_b_c().inverse()); }

// The loop's current keyframe and its covisible neighbours, moved by the loop's
// correction, with what the later steps need of the move.
struct CorrectedGroup {
  std::vector<std::shared_ptr<KeyFrame>> keyframes;
  std::unordered_map<KeyframeId, Pose3> old_T_c_w;          // before the correction
  std::unordered_map<KeyframeId, Sim3> corrected;           // after it (world -> camera)
  std::unordered_map<MapPointId, KeyframeId> corrected_by;  // each moved point, by the keyframe that moved it
};

// An inertial map knows its roll and pitch: the loop's correction of the world
// keeps only its turn about the map's up (minus its gravity's direction) and
// moves the current keyframe's camera where the full correction puts it
// (ORB-SLAM3 zeroes the correction's roll and pitch the same way).
Sim3 yaw_only_correction(const Pose3& T_a_w_old, const Sim3& S_a_w_new, const Eigen::Vector3d& up) {
  const Pose3 W = rigid_pose_c_w(S_a_w_new).inverse() * T_a_w_old;  // old world -> new world
  return Sim3(T_a_w_old * yaw_only_transform(W, T_a_w_old.inverse().t, up, up).inverse());
}

// 1. The group and its corrected poses; its points move with the keyframe that
// sees them first.
CorrectedGroup correct_group(Map& map, const PlaceMatch& loop, const FrameCamera& cam, LoopCorrectionStats& stats) {
  CorrectedGroup g;
  const auto& current = loop.current;
  g.keyframes.push_back(current);
  for (const auto& edge : current->connections())
    if (auto kf = map.keyframe(edge.keyframe); kf && !kf->is_bad()) g.keyframes.push_back(std::move(kf));
  const Pose3 T_a_w_old = current->T_w_c().inverse();
  const auto inertial = map.inertial_state();
  const Sim3 S_a_w_new =
      inertial ? yaw_only_correction(T_a_w_old, loop.S_c_w_corrected, inertial->up()) : loop.S_c_w_corrected;
  for (const auto& kf : g.keyframes) {
    g.old_T_c_w[kf->id()] = kf->T_w_c().inverse();
    g.corrected[kf->id()] = propagate_correction(g.old_T_c_w[kf->id()], T_a_w_old, S_a_w_new);
  }
  const Pose3 T_w_c_new = rigid_pose_c_w(S_a_w_new).inverse();
  const Pose3 T_w_c_old = T_a_w_old.inverse();
  stats.correction_m = translation_distance(T_w_c_old, T_w_c_new);
  stats.correction_deg = rotation_distance(T_w_c_old, T_w_c_new) * 180.0 / M_PI;
  stats.correction_scale = 1.0 / S_a_w_new.s;  // lengths about the current keyframe are multiplied by it

  std::vector<std::shared_ptr<MapPoint>> moved;
  for (const auto& kf : g.keyframes) {
    for (const auto& mp : kf->map_points()) {
      if (mp->is_bad() || !g.corrected_by.emplace(mp->id(), kf->id()).second) continue;
      mp->set_p_w(correct_point(g.old_T_c_w[kf->id()], g.corrected[kf->id()], mp->p_w()));
      moved.push_back(mp);
    }
  }
  for (const auto& kf : g.keyframes) set_camera_pose(*kf, rigid_pose_c_w(g.corrected[kf->id()]));
  for (const auto& mp : moved) update_normal_and_distances(*mp, cam.pyramid);
  stats.group_keyframes = g.keyframes.size();
  stats.corrected_points = moved.size();
  return g;
}

// 2. The loop window's points fused into the group; returns the covisibility links
// that now cross the loop (new since the fusion, outside the group), by keyframe.
std::unordered_map<KeyframeId, std::vector<KeyframeId>> fuse_across_loop(Map& map, const PlaceMatch& loop,
                                                                         const CorrectedGroup& g,
                                                                         const FrameCamera& cam,
                                                                         const LoopCorrectionOptions& options,
                                                                         LoopCorrectionStats& stats) {
  std::unordered_set<KeyframeId> group_ids;
  for (const auto& kf : g.keyframes) group_ids.insert(kf->id());
  std::unordered_map<KeyframeId, std::unordered_set<KeyframeId>> previous;
  for (const auto& kf : g.keyframes)
    for (const auto& edge : kf->connections()) previous[kf->id()].insert(edge.keyframe);
  for (const auto& kf : g.keyframes) {
    const FusionStats f = fuse_into_keyframe(map, kf, loop.window_points, cam, options.fusion_th);
    stats.observations_fused += static_cast<std::size_t>(f.added);
    stats.points_fused += static_cast<std::size_t>(f.merged);
  }
  std::unordered_map<KeyframeId, std::vector<KeyframeId>> loop_links;
  for (const auto& kf : g.keyframes) {
    kf->update_connections();
    for (const auto& edge : kf->connections()) {
      if (previous[kf->id()].count(edge.keyframe) || group_ids.count(edge.keyframe)) continue;
      loop_links[kf->id()].push_back(edge.keyframe);
      ++stats.new_links;
    }
  }
  return loop_links;
}

// 3. The essential graph over the whole map, optimised: loop links measured with
// the corrected poses (what the loop says), the spanning tree, older loop edges and
// strong covisibility with the poses from before the loop (the drifted odometry).
// Returns each keyframe's pose at the graph's start and after it.
struct GraphSolution {
  std::unordered_map<KeyframeId, Sim3> initial, optimised;
};

GraphSolution optimise_essential_graph(Map& map, const PlaceMatch& loop, CorrectedGroup& g,
                                       const std::unordered_map<KeyframeId, std::vector<KeyframeId>>& loop_links,
                                       const LoopCorrectionOptions& options, LoopCorrectionStats& stats) {
  GraphSolution out;
  const auto keyframes = map.keyframes();  // by id: the first is the map's origin
  std::vector<PoseGraphNode> nodes;
  std::unordered_map<KeyframeId, Sim3> before;  // pre-loop (non-corrected)
  for (const auto& kf : keyframes) {
    if (kf->is_bad()) continue;
    const auto it = g.corrected.find(kf->id());
    const Pose3 T_c_w_now = kf->T_w_c().inverse();
    out.initial[kf->id()] = it != g.corrected.end() ? it->second : Sim3(T_c_w_now);
    before[kf->id()] = it != g.corrected.end() ? Sim3(g.old_T_c_w[kf->id()]) : Sim3(T_c_w_now);
    nodes.push_back({kf->id(), out.initial[kf->id()], nodes.empty()});
  }
  std::vector<PoseGraphEdge> edges;
  std::set<std::pair<KeyframeId, KeyframeId>> linked;
  auto add_edge = [&](KeyframeId i, KeyframeId j, const std::unordered_map<KeyframeId, Sim3>& poses,
                      PoseGraphEdgeKind kind) {
    if (i == j || !poses.count(i) || !poses.count(j)) return;
    if (!linked.insert({std::min(i, j), std::max(i, j)}).second) return;
    edges.push_back({i, j, poses.at(i) * poses.at(j).inverse(), 1.0, kind});
  };
  add_edge(loop.current->id(), loop.matched->id(), out.initial, PoseGraphEdgeKind::kLoop);
  for (const auto& [i, links] : loop_links) {
    const auto kf = map.keyframe(i);
    if (!kf) continue;
    for (const KeyframeId j : links)
      if (kf->weight(j) >= options.strong_covisibility) add_edge(i, j, out.initial, PoseGraphEdgeKind::kLoop);
  }
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
  graph_options.fix_scale = !loop.scale_free;  // a metric map keeps its scale everywhere
  const auto inertial = map.inertial_state();
  graph_options.yaw_only = inertial.has_value();  // and an inertial one knows its roll and pitch
  if (inertial) graph_options.yaw_axis = inertial->up();
  stats.four_dof = graph_options.yaw_only;
  const auto graph_start = std::chrono::steady_clock::now();
  const EssentialGraphResult result = optimize_essential_graph(nodes, edges, graph_options);
  stats.graph_ms = ms_since(graph_start);
  stats.graph_nodes = nodes.size();
  stats.graph_edges = edges.size();
  for (const auto& node : result.nodes) out.optimised[node.id] = node.S_n_w;
  return out;
}

// 4. Keyframes take their optimised poses; points follow the keyframe that
// corrected them, else their reference keyframe.
void apply_solution(Map& map, const CorrectedGroup& g, const GraphSolution& solution, const FrameCamera& cam) {
  for (const auto& kf : map.keyframes())
    if (const auto it = solution.optimised.find(kf->id()); it != solution.optimised.end() && !kf->is_bad()) {
      set_camera_pose(*kf, rigid_pose_c_w(it->second));
      // Lengths about the keyframe were multiplied by 1 / s (the points below
      // follow it the same way; a metric map's s is 1).
      if (it->second.s != 1.0) kf->scale_units(1.0 / it->second.s);
    }
  for (const auto& mp : map.map_points()) {
    if (mp->is_bad()) continue;
    KeyframeId ref = 0;
    if (const auto it = g.corrected_by.find(mp->id()); it != g.corrected_by.end()) {
      ref = it->second;
    } else if (const auto r = mp->reference_keyframe_id()) {
      ref = *r;
    } else {
      continue;
    }
    const auto from = solution.initial.find(ref);
    const auto to = solution.optimised.find(ref);
    if (from == solution.initial.end() || to == solution.optimised.end()) continue;
    mp->set_p_w(to->second.inverse() * (from->second * mp->p_w()));
    update_normal_and_distances(*mp, cam.pyramid);
  }
}

}  // namespace

void LoopCorrectionOptions::check() const {
  ORBATLAS_CHECK(std::isfinite(fusion_th) && fusion_th >= 0.0f,
                 "loop correction: fusion_th must be a finite value >= 0, not " << fusion_th);
  ORBATLAS_CHECK(strong_covisibility >= 0,
                 "loop correction: strong_covisibility must be >= 0, not " << strong_covisibility);
  graph.check();
}

LoopCorrectionStats correct_loop(Map& map, const PlaceMatch& loop, const FrameCamera& cam,
                                 const LoopCorrectionOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  options.check();
  LoopCorrectionStats stats;
  ORBATLAS_CHECK(loop.current && loop.matched, "loop correction needs both keyframes");
  ORBATLAS_CHECK(!loop.scale_free || !map.inertial_state(),
                 "loop correction: map " << map.id() << " is inertial (metric); its loop cannot change the scale");
  ORBATLAS_CHECK(loop.current->map_id() == map.id() && loop.matched->map_id() == map.id(),
                 "loop correction: keyframes " << loop.current->id() << " and " << loop.matched->id()
                                               << " are not both in map " << map.id());
  if (loop.current->is_bad() || loop.matched->is_bad()) return stats;

  CorrectedGroup group = correct_group(map, loop, cam, stats);
  const auto loop_links = fuse_across_loop(map, loop, group, cam, options, stats);
  const GraphSolution solution = optimise_essential_graph(map, loop, group, loop_links, options, stats);
  apply_solution(map, group, solution, cam);
  loop.current->add_loop_edge(loop.matched);
  stats.total_ms = ms_since(start);
  return stats;
}

}  // namespace orbatlas
