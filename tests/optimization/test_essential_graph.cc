// Essential-graph (pose-graph) optimisation over similarities against exact
// synthetic ground truth: a loop of poses whose estimate drifted, with exact
// relative measurements (odometry, covisibility and the loop edge) — the truth is
// the zero-cost solution and must be recovered.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "core/common/error.h"
#include "core/geometry/sim3.h"
#include "core/geometry/so3.h"
#include "core/optimization/essential_graph.h"

namespace orbatlas {
namespace {

constexpr double kDegree = M_PI / 180.0;

Eigen::Vector3d gaussian3(std::mt19937& rng, double sigma = 1.0) {
  std::normal_distribution<double> n(0.0, sigma);
  return Eigen::Vector3d(n(rng), n(rng), n(rng));
}

// Node k of n on a circle of `radius` (z up), the camera looking along the path,
// with some wobble; `scale_drift` gives node k the scale 1 + scale_drift * k / n
// (the truth of a monocular map whose keyframes carry similarity poses).
std::vector<Sim3> circle_truth(int n, double radius, double scale_drift, std::mt19937& rng) {
  std::vector<Sim3> truth;
  for (int k = 0; k < n; ++k) {
    const double a = 2.0 * M_PI * k / n;
    const Eigen::Vector3d position(radius * std::cos(a), radius * std::sin(a), 0.3 * std::sin(3.0 * a));
    // Camera z along the tangent, x outwards, y = z cross x.
    const Eigen::Vector3d z(-std::sin(a), std::cos(a), 0.0);
    const Eigen::Vector3d x(std::cos(a), std::sin(a), 0.0);
    Eigen::Matrix3d R_w_c;
    R_w_c << x, z.cross(x), z;
    const Eigen::Quaterniond q_w_c = Eigen::Quaterniond(R_w_c) * so3_exp(gaussian3(rng, 2.0 * kDegree));
    const Sim3 S_w_c(q_w_c, position, 1.0 / (1.0 + scale_drift * k / n));
    truth.push_back(S_w_c.inverse());  // S_c_w
  }
  return truth;
}

// The estimate before the loop correction: exact up to node `from`, then each
// node's world seen through a drift growing by `step` per node.
std::vector<Sim3> drifted(const std::vector<Sim3>& truth, int from, const Sim3& step) {
  std::vector<Sim3> out = truth;
  Sim3 drift;
  for (std::size_t k = static_cast<std::size_t>(from); k < truth.size(); ++k) {
    drift = drift * step;
    out[k] = truth[k] * drift;  // S_c_w of a world moved by the drift
  }
  return out;
}

PoseGraphEdge exact_edge(const std::vector<Sim3>& truth, std::size_t i, std::size_t j, PoseGraphEdgeKind kind) {
  return PoseGraphEdge{i, j, truth[i] * truth[j].inverse(), 1.0, kind};
}

// Chain (i, i+1), covisibility (i, i+k) for k = 2..covisibility_span, and loop
// edges between the last `loops` nodes and the first ones.
std::vector<PoseGraphEdge> exact_edges(const std::vector<Sim3>& truth, int covisibility_span, int loops) {
  const std::size_t n = truth.size();
  std::vector<PoseGraphEdge> edges;
  for (std::size_t i = 0; i + 1 < n; ++i)
    edges.push_back(exact_edge(truth, i + 1, i, PoseGraphEdgeKind::kSpanningTree));
  for (int k = 2; k <= covisibility_span; ++k)
    for (std::size_t i = 0; i + static_cast<std::size_t>(k) < n; ++i)
      edges.push_back(exact_edge(truth, i, i + static_cast<std::size_t>(k), PoseGraphEdgeKind::kCovisibility));
  for (int l = 0; l < loops; ++l)
    edges.push_back(
        exact_edge(truth, n - 1 - static_cast<std::size_t>(l), static_cast<std::size_t>(l), PoseGraphEdgeKind::kLoop));
  return edges;
}

std::vector<PoseGraphNode> make_nodes(const std::vector<Sim3>& poses, std::size_t fixed) {
  std::vector<PoseGraphNode> nodes;
  for (std::size_t k = 0; k < poses.size(); ++k) nodes.push_back(PoseGraphNode{k, poses[k], k == fixed});
  return nodes;
}

struct Errors {
  double rotation = 0.0, position = 0.0, log_scale = 0.0;  // worst over the nodes
};

// Camera positions (S_w_c translation) and orientations against the truth.
Errors errors(const std::vector<PoseGraphNode>& nodes, const std::vector<Sim3>& truth) {
  Errors e;
  for (std::size_t k = 0; k < nodes.size(); ++k) {
    e.rotation = std::max(e.rotation, sim3_rotation_distance(nodes[k].S_n_w, truth[k]));
    e.position = std::max(e.position, (nodes[k].S_n_w.inverse().t - truth[k].inverse().t).norm());
    e.log_scale = std::max(e.log_scale, sim3_log_scale_distance(nodes[k].S_n_w, truth[k]));
  }
  return e;
}

std::vector<PoseGraphNode> to_nodes(const std::vector<Sim3>& poses) { return make_nodes(poses, poses.size()); }

void run_loop_case(bool fix_scale) {
  std::mt19937 rng(fix_scale ? 1 : 2);
  const std::vector<Sim3> truth = circle_truth(50, 5.0, fix_scale ? 0.0 : 0.3, rng);
  // 0.4 deg, 2 cm (and 0.4% scale in Sim3 mode) of drift per node after node 10.
  const Sim3 step(so3_exp(Eigen::Vector3d(0.1, 0.3, 1.0).normalized() * 0.4 * kDegree),
                  Eigen::Vector3d(0.02, -0.01, 0.005), fix_scale ? 1.0 : 1.004);
  const std::vector<Sim3> initial = drifted(truth, 10, step);
  const std::vector<PoseGraphNode> nodes = make_nodes(initial, 0);
  const std::vector<PoseGraphEdge> edges = exact_edges(truth, 2, 1);
  EssentialGraphOptions options;
  options.fix_scale = fix_scale;
  const EssentialGraphResult r = optimize_essential_graph(nodes, edges, options);

  const Errors before = errors(to_nodes(initial), truth);
  const Errors after = errors(r.nodes, truth);
  EXPECT_GT(before.position, 0.3);  // the drift is real
  EXPECT_LE(after.rotation, 1e-6);
  EXPECT_LE(after.position, 1e-6);
  EXPECT_LE(after.log_scale, 1e-6);
  ASSERT_EQ(r.nodes.size(), nodes.size());
  for (std::size_t k = 0; k < nodes.size(); ++k) EXPECT_EQ(r.nodes[k].id, nodes[k].id);
  // The fixed node is untouched, bit for bit.
  EXPECT_EQ(r.nodes[0].S_n_w.matrix(), nodes[0].S_n_w.matrix());
  if (fix_scale) {
    for (const PoseGraphNode& node : r.nodes) EXPECT_EQ(node.S_n_w.s, 1.0);
  }
}

TEST(EssentialGraph, RecoversDriftedLoopSim3) { run_loop_case(false); }

TEST(EssentialGraph, RecoversDriftedLoopScaleFixed) { run_loop_case(true); }

// The loop-closing situation: odometry edges measured on the drifted estimate
// (the old poses), one loop edge with the true relative pose. No solution fits
// all; the optimiser spreads the loop error, so the worst error must drop a lot.
TEST(EssentialGraph, SpreadsLoopErrorOverDriftedOdometry) {
  std::mt19937 rng(3);
  const std::vector<Sim3> truth = circle_truth(50, 5.0, 0.0, rng);
  const Sim3 step(so3_exp(Eigen::Vector3d(0.0, 0.0, 1.0) * 0.3 * kDegree), Eigen::Vector3d(0.01, 0.0, 0.0), 1.0);
  const std::vector<Sim3> initial = drifted(truth, 0, step);
  std::vector<PoseGraphEdge> edges = exact_edges(initial, 2, 0);
  edges.push_back(exact_edge(truth, 49, 0, PoseGraphEdgeKind::kLoop));
  edges.back().weight = 10.0;
  EssentialGraphOptions options;
  options.fix_scale = true;
  const EssentialGraphResult r = optimize_essential_graph(make_nodes(initial, 0), edges, options);
  const Errors before = errors(to_nodes(initial), truth);
  const Errors after = errors(r.nodes, truth);
  // The loop edge itself is (nearly) satisfied.
  const Sim3 loop = r.nodes[49].S_n_w * r.nodes[0].S_n_w.inverse();
  const Sim3 loop_true = truth[49] * truth[0].inverse();
  EXPECT_LT(after.position, 0.5 * before.position);
  EXPECT_LT(after.rotation, 0.5 * before.rotation);
  EXPECT_LT(sim3_rotation_distance(loop, loop_true), 0.1 * before.rotation);
}

// An inertial map (gravity along the world's -z): the drift is a turn about z
// and a translation, which the 4-DoF graph undoes exactly; every node keeps
// where it sees gravity (the direction of the world's z in its frame) bit for
// bit up to rounding.
TEST(EssentialGraph, YawOnlyRecoversAYawDriftAndKeepsEveryNodesGravity) {
  std::mt19937 rng(5);
  const std::vector<Sim3> truth = circle_truth(50, 5.0, 0.0, rng);
  const Sim3 step(so3_exp(Eigen::Vector3d(0.0, 0.0, 1.0) * 0.4 * kDegree), Eigen::Vector3d(0.02, -0.01, 0.005), 1.0);
  const std::vector<Sim3> initial = drifted(truth, 10, step);
  EssentialGraphOptions options;
  options.fix_scale = true;
  options.yaw_only = true;
  const EssentialGraphResult r = optimize_essential_graph(make_nodes(initial, 0), exact_edges(truth, 2, 1), options);
  const Errors before = errors(to_nodes(initial), truth);
  const Errors after = errors(r.nodes, truth);
  double gravity_change = 0.0;
  for (std::size_t k = 0; k < r.nodes.size(); ++k)
    gravity_change =
        std::max(gravity_change,
                 ((r.nodes[k].S_n_w.q * Eigen::Vector3d::UnitZ()) - (initial[k].q * Eigen::Vector3d::UnitZ())).norm());
  EXPECT_GT(before.position, 0.3);
  EXPECT_LE(after.rotation, 1e-6);
  EXPECT_LE(after.position, 1e-6);
  EXPECT_LE(gravity_change, 1e-12);

  options.fix_scale = false;  // a free scale has no place in a metric inertial map
  EXPECT_THROW(optimize_essential_graph(make_nodes(initial, 0), exact_edges(truth, 2, 1), options), Error);
}

// The same in a world whose up is tilted (a map whose refinements tilted its
// gravity instead of turning it): the drift turns about that up, the graph
// turns the nodes about it and undoes the drift exactly, and every node keeps
// where it sees the world's up.
TEST(EssentialGraph, YawOnlyTurnsAboutATiltedUp) {
  std::mt19937 rng(5);
  const Eigen::Quaterniond tilt = so3_exp(Eigen::Vector3d(0.012, -0.007, 0.0));
  const Eigen::Vector3d up = tilt * Eigen::Vector3d::UnitZ();
  std::vector<Sim3> truth = circle_truth(50, 5.0, 0.0, rng);
  for (Sim3& s : truth) s = s * Sim3(tilt.conjugate(), Eigen::Vector3d::Zero(), 1.0);  // the world tilted
  const Sim3 step(so3_exp(up * 0.4 * kDegree), Eigen::Vector3d(0.02, -0.01, 0.005), 1.0);
  const std::vector<Sim3> initial = drifted(truth, 10, step);
  EssentialGraphOptions options;
  options.fix_scale = true;
  options.yaw_only = true;
  options.yaw_axis = up;
  const EssentialGraphResult r = optimize_essential_graph(make_nodes(initial, 0), exact_edges(truth, 2, 1), options);
  const Errors before = errors(to_nodes(initial), truth);
  const Errors after = errors(r.nodes, truth);
  double up_change = 0.0;
  for (std::size_t k = 0; k < r.nodes.size(); ++k)
    up_change = std::max(up_change, ((r.nodes[k].S_n_w.q * up) - (initial[k].q * up)).norm());
  EXPECT_GT(before.position, 0.3);
  EXPECT_LE(after.rotation, 1e-6);
  EXPECT_LE(after.position, 1e-6);
  EXPECT_LE(up_change, 1e-12);
  // About z instead, the graph cannot undo a turn about the tilted up.
  options.yaw_axis = Eigen::Vector3d::UnitZ();
  const EssentialGraphResult about_z =
      optimize_essential_graph(make_nodes(initial, 0), exact_edges(truth, 2, 1), options);
  EXPECT_GT(errors(about_z.nodes, truth).rotation, 1e-4);
}

TEST(EssentialGraph, NodesWithoutEdgesAreUntouched) {
  std::mt19937 rng(4);
  const std::vector<Sim3> truth = circle_truth(10, 2.0, 0.0, rng);
  std::vector<PoseGraphNode> nodes = make_nodes(truth, 0);
  nodes.push_back(PoseGraphNode{100, Sim3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(1, 2, 3), 2.0), false});
  const EssentialGraphResult r = optimize_essential_graph(nodes, exact_edges(truth, 1, 0));
  EXPECT_EQ(r.nodes.back().S_n_w.matrix(), nodes.back().S_n_w.matrix());
  EXPECT_LE(errors(std::vector<PoseGraphNode>(r.nodes.begin(), r.nodes.end() - 1), truth).position, 1e-9);
  // No edges at all: everything comes back as given.
  const EssentialGraphResult none = optimize_essential_graph(nodes, {});
  EXPECT_EQ(none.iterations, 0);
  for (std::size_t k = 0; k < nodes.size(); ++k) EXPECT_EQ(none.nodes[k].S_n_w.matrix(), nodes[k].S_n_w.matrix());
}

TEST(EssentialGraph, RejectsInconsistentGraphs) {
  std::mt19937 rng(5);
  const std::vector<Sim3> truth = circle_truth(5, 2.0, 0.0, rng);
  const std::vector<PoseGraphNode> nodes = make_nodes(truth, 0);
  const std::vector<PoseGraphEdge> edges = exact_edges(truth, 1, 0);
  EXPECT_NO_THROW(optimize_essential_graph(nodes, edges));

  std::vector<PoseGraphEdge> unknown = edges;
  unknown.push_back(PoseGraphEdge{0, 77, Sim3(), 1.0, PoseGraphEdgeKind::kLoop});
  EXPECT_THROW(optimize_essential_graph(nodes, unknown), Error);
  std::vector<PoseGraphEdge> self = edges;
  self.push_back(PoseGraphEdge{2, 2, Sim3(), 1.0, PoseGraphEdgeKind::kCovisibility});
  EXPECT_THROW(optimize_essential_graph(nodes, self), Error);
  std::vector<PoseGraphEdge> weightless = edges;
  weightless[1].weight = 0.0;
  EXPECT_THROW(optimize_essential_graph(nodes, weightless), Error);
  weightless[1].weight = std::nan("");
  EXPECT_THROW(optimize_essential_graph(nodes, weightless), Error);

  std::vector<PoseGraphNode> duplicate = nodes;
  duplicate[3].id = duplicate[1].id;
  EXPECT_THROW(optimize_essential_graph(duplicate, edges), Error);

  // Gauge: no fixed node, or a separate part of the graph without one.
  EXPECT_THROW(optimize_essential_graph(to_nodes(truth), edges), Error);
  std::vector<PoseGraphNode> two_parts = nodes;
  two_parts.push_back(PoseGraphNode{10, truth[1], false});
  two_parts.push_back(PoseGraphNode{11, truth[2], false});
  std::vector<PoseGraphEdge> split = edges;
  split.push_back(PoseGraphEdge{10, 11, truth[1] * truth[2].inverse(), 1.0, PoseGraphEdgeKind::kCovisibility});
  EXPECT_THROW(optimize_essential_graph(two_parts, split), Error);
  two_parts.back().fixed = true;
  EXPECT_NO_THROW(optimize_essential_graph(two_parts, split));
}

TEST(EssentialGraph, Timing500Nodes2000Edges) {
  for (const bool fix_scale : {false, true}) {
    std::mt19937 rng(6);
    const std::vector<Sim3> truth = circle_truth(500, 30.0, fix_scale ? 0.0 : 0.3, rng);
    const Sim3 step(so3_exp(Eigen::Vector3d(0.2, -0.1, 1.0).normalized() * 0.05 * kDegree),
                    Eigen::Vector3d(0.005, 0.002, -0.001), fix_scale ? 1.0 : 1.0005);
    const std::vector<Sim3> initial = drifted(truth, 20, step);
    // 499 chain + 498 + 497 + 496 covisibility + 10 loop edges = 2,000.
    const std::vector<PoseGraphEdge> edges = exact_edges(truth, 4, 10);
    ASSERT_EQ(edges.size(), 2000u);
    EssentialGraphOptions options;
    options.fix_scale = fix_scale;
    const EssentialGraphResult r = optimize_essential_graph(make_nodes(initial, 0), edges, options);
    const Errors before = errors(to_nodes(initial), truth);
    const Errors after = errors(r.nodes, truth);
    EXPECT_GT(before.position, 1.0);
    EXPECT_LE(after.position, 1e-6);
    EXPECT_LE(after.rotation, 1e-6);
    EXPECT_LE(after.log_scale, 1e-6);
  }
}

}  // namespace
}  // namespace orbatlas
