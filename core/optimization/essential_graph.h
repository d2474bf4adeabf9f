#pragma once
// Pose-graph optimisation over similarities: ORB-SLAM's
// Optimizer::OptimizeEssentialGraph, generic (no map types), with Ceres.
//
// CONVENTIONS (read carefully)
// - Node n carries S_n_w: the similarity mapping WORLD points INTO node n's frame,
//   p_n = S_n_w * p_w = s R p_w + t (ORB-SLAM's Scw of a keyframe's camera; any
//   per-node frame works as long as nodes and edges agree). A keyframe with rigid
//   pose T_c_w enters as Sim3(T_c_w), scale 1.
// - Edge (i, j) carries the measured S_i_j: it maps points of node j's frame into
//   node i's frame, so a consistent graph has S_i_j = S_i_w * S_j_w^-1. A keyframe
//   edge built from the (pre-loop) poses is S_i_j = S_i_w_old * S_j_w_old^-1; a
//   loop edge carries the corrected relative similarity.
// - Residual (7): the error similarity E = S_i_j * S_j_w * S_i_w^-1 (the identity
//   when the edge is satisfied), r = sqrt(weight) * [log(R_E) (3), t_E (3),
//   log(s_E) (1)]. ORB-SLAM uses g2o's Sim3 log, whose translation part is
//   V^-1 t_E; the two agree to first order at E = I and both vanish exactly there.
//   ORB-SLAM weighs every edge with the identity information (weight 1).
// - Parameters per node: quaternion (EigenQuaternionManifold), translation, log
//   scale. fix_scale keeps every node's log scale constant (stereo / RGB-D:
//   scale 1 stays exactly 1, the solve is over SE3). Fixed nodes are constant.
// - Solver: Levenberg-Marquardt, 20 iterations (ORB-SLAM), sparse normal Cholesky.
//
// The result lists the nodes in input order with their optimised S_n_w. Applying
// them to keyframes and map points: sim3_correction.h (rigid_pose_c_w, correct_point).
#include <cstdint>
#include <vector>

#include "core/geometry/sim3.h"

namespace orbatlas {

struct PoseGraphNode {
  std::uint64_t id = 0;  // unique (e.g. the keyframe id)
  Sim3 S_n_w;            // world -> node frame
  bool fixed = false;    // kept exactly (ORB-SLAM fixes the loop keyframe / welding window)
};

enum class PoseGraphEdgeKind {
  kSpanningTree,  // keyframe -> parent
  kCovisibility,  // strong covisibility (ORB-SLAM: >= 100 shared points)
  kLoop,          // loop or merge edge
};

struct PoseGraphEdge {
  std::uint64_t i = 0;
  std::uint64_t j = 0;
  Sim3 S_i_j;           // measured: node j's frame -> node i's frame
  double weight = 1.0;  // multiplies the squared residual (information scale)
  PoseGraphEdgeKind kind = PoseGraphEdgeKind::kSpanningTree;
};

struct EssentialGraphOptions {
  int max_iterations = 20;  // ORB-SLAM's OptimizeEssentialGraph
  bool fix_scale = false;   // stereo / RGB-D / mature inertial maps
  // Inertial maps: each node turns only about the world's up (`yaw_axis`,
  // minus the map's gravity direction; z when gravity is along -z) and moves
  // (4 degrees of freedom, ORB-SLAM3's OptimizeEssentialGraph4DoF); roll and
  // pitch, which gravity makes observable, stay as the nodes came. Use with
  // fix_scale.
  bool yaw_only = false;
  Eigen::Vector3d yaw_axis = Eigen::Vector3d::UnitZ();
  int num_threads = 1;

  // Throws Error naming the first value out of range.
  void check() const;
};

struct EssentialGraphResult {
  std::vector<PoseGraphNode> nodes;  // input order, optimised S_n_w
  int iterations = 0;
  double initial_cost = 0.0;  // Ceres cost (half the sum of squared residuals)
  double final_cost = 0.0;
  double time_ms = 0.0;
};

// Throws Error on duplicate node ids, an edge naming an unknown node or linking a
// node to itself, a non-positive or non-finite weight, or no fixed node among the
// nodes used by edges (the gauge: 7 free dof otherwise). Nodes in no edge are
// returned unchanged.
EssentialGraphResult optimize_essential_graph(const std::vector<PoseGraphNode>& nodes,
                                              const std::vector<PoseGraphEdge>& edges,
                                              const EssentialGraphOptions& options = {});

}  // namespace orbatlas
