#include "core/optimization/essential_graph.h"

#include <ceres/autodiff_cost_function.h>
#include <ceres/autodiff_manifold.h>
#include <ceres/manifold.h>
#include <ceres/problem.h>
#include <ceres/rotation.h>
#include <ceres/solver.h>

#include <array>
#include <chrono>
#include <memory>
#include <cmath>
#include <numeric>
#include <unordered_map>

#include "core/common/error.h"

namespace orbatlas {
namespace {

// E = S_i_j * S_j_w * S_i_w^-1 as a 7-vector (see the header). Parameter blocks
// (q_i[4], t_i[3], log_s_i[1], q_j[4], t_j[3], log_s_j[1]).
struct EdgeResidual {
  Eigen::Quaterniond q_ij;
  Eigen::Vector3d t_ij;
  double s_ij = 1.0;
  double log_s_ij = 0.0;
  double sqrt_weight = 1.0;

  template <typename T>
  bool operator()(const T* q_i_, const T* t_i_, const T* ls_i, const T* q_j_, const T* t_j_, const T* ls_j,
                  T* r) const {
    using std::exp;  // ceres::exp for Jets by argument-dependent lookup
    using Vec3 = Eigen::Matrix<T, 3, 1>;
    const Eigen::Map<const Eigen::Quaternion<T>> q_i(q_i_), q_j(q_j_);
    const Eigen::Map<const Vec3> t_i(t_i_), t_j(t_j_);
    // A = S_j_w * S_i_w^-1 = (q_j q_i^-1, t_j - s_A q_A t_i, s_j / s_i).
    const Eigen::Quaternion<T> q_a = q_j * q_i.conjugate();
    const T ls_a = ls_j[0] - ls_i[0];
    const Vec3 t_a = t_j - exp(ls_a) * (q_a * t_i);
    // E = S_i_j * A.
    const Eigen::Quaternion<T> q_m = q_ij.cast<T>();
    const Eigen::Quaternion<T> q_e = q_m * q_a;
    const Vec3 t_e = T(s_ij) * (q_m * t_a) + t_ij.cast<T>();
    const T ls_e = T(log_s_ij) + ls_a;
    const T q_e_wxyz[4] = {q_e.w(), q_e.x(), q_e.y(), q_e.z()};
    T angle_axis[3];
    ceres::QuaternionToAngleAxis(q_e_wxyz, angle_axis);  // shortest rotation; smooth at identity
    for (int k = 0; k < 3; ++k) {
      r[k] = T(sqrt_weight) * angle_axis[k];
      r[3 + k] = T(sqrt_weight) * t_e[k];
    }
    r[6] = T(sqrt_weight) * ls_e;
    return true;
  }
};

// A node's rotation that turns only about the world's up (`axis`, unit: z
// when the map's gravity is along -z, the map's up when its refinements tilted
// its gravity): S_n_w's quaternion (x y z w) times a rotation by delta about the
// axis on the right (R_n_w R_axis(delta): the node turned about the world's up).
struct WorldYawPlus {
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();

  template <typename T>
  bool Plus(const T* x, const T* delta, T* x_plus_delta) const {
    const Eigen::Map<const Eigen::Quaternion<T>> q(x);
    const T half = delta[0] / T(2);
    const T s = sin(half);
    const Eigen::Quaternion<T> yaw(cos(half), s * T(axis.x()), s * T(axis.y()), s * T(axis.z()));
    Eigen::Map<Eigen::Quaternion<T>> out(x_plus_delta);
    out = q * yaw;
    return true;
  }
  template <typename T>
  bool Minus(const T* y, const T* x, T* y_minus_x) const {
    const Eigen::Map<const Eigen::Quaternion<T>> qy(y), qx(x);
    const Eigen::Quaternion<T> d = qx.conjugate() * qy;  // about the axis when y = Plus(x, delta)
    const T along = d.x() * T(axis.x()) + d.y() * T(axis.y()) + d.z() * T(axis.z());
    y_minus_x[0] = T(2) * atan2(along, d.w());
    return true;
  }
};

struct NodeParameters {
  std::array<double, 4> q{0.0, 0.0, 0.0, 1.0};  // Eigen memory order (x, y, z, w)
  std::array<double, 3> t{0.0, 0.0, 0.0};
  std::array<double, 1> log_s{0.0};
};

// Union-find over node indices, to check that every connected part has a fixed node.
std::size_t find_root(std::vector<std::size_t>& parent, std::size_t a) {
  while (parent[a] != a) a = parent[a] = parent[parent[a]];
  return a;
}

}  // namespace

void EssentialGraphOptions::check() const {
  ORBATLAS_CHECK(max_iterations >= 0, "essential graph: max_iterations must be >= 0, not " << max_iterations);
  ORBATLAS_CHECK(num_threads >= 1, "essential graph: num_threads must be >= 1, not " << num_threads);
  ORBATLAS_CHECK(!yaw_only || fix_scale, "essential graph: yaw_only needs fix_scale (a metric inertial map)");
  ORBATLAS_CHECK(yaw_axis.allFinite() && yaw_axis.norm() > 0.5,
                 "essential graph: yaw_axis must be a unit vector, not (" << yaw_axis.transpose() << ")");
}

EssentialGraphResult optimize_essential_graph(const std::vector<PoseGraphNode>& nodes,
                                              const std::vector<PoseGraphEdge>& edges,
                                              const EssentialGraphOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  options.check();

  std::unordered_map<std::uint64_t, std::size_t> index;
  index.reserve(nodes.size());
  for (std::size_t k = 0; k < nodes.size(); ++k)
    ORBATLAS_CHECK(index.emplace(nodes[k].id, k).second, "essential graph: duplicate node id " << nodes[k].id);

  std::vector<std::size_t> parent(nodes.size());
  std::iota(parent.begin(), parent.end(), std::size_t{0});
  std::vector<std::uint8_t> used(nodes.size(), 0);
  std::vector<std::pair<std::size_t, std::size_t>> ends;
  ends.reserve(edges.size());
  for (const PoseGraphEdge& e : edges) {
    const auto i = index.find(e.i);
    const auto j = index.find(e.j);
    ORBATLAS_CHECK(i != index.end(), "essential graph: edge (" << e.i << ", " << e.j << ") names unknown node " << e.i);
    ORBATLAS_CHECK(j != index.end(), "essential graph: edge (" << e.i << ", " << e.j << ") names unknown node " << e.j);
    ORBATLAS_CHECK(e.i != e.j, "essential graph: edge links node " << e.i << " to itself");
    ORBATLAS_CHECK(e.weight > 0.0 && std::isfinite(e.weight),
                   "essential graph: edge (" << e.i << ", " << e.j << ") has weight " << e.weight);
    ends.emplace_back(i->second, j->second);
    used[i->second] = used[j->second] = 1;
    parent[find_root(parent, i->second)] = find_root(parent, j->second);
  }
  std::vector<std::uint8_t> part_fixed(nodes.size(), 0);
  for (std::size_t k = 0; k < nodes.size(); ++k)
    if (used[k] && nodes[k].fixed) part_fixed[find_root(parent, k)] = 1;
  for (std::size_t k = 0; k < nodes.size(); ++k)
    ORBATLAS_CHECK(!used[k] || part_fixed[find_root(parent, k)], "essential graph: the part of the graph holding node "
                                                                     << nodes[k].id << " has no fixed node (gauge)");

  EssentialGraphResult result;
  result.nodes = nodes;
  if (edges.empty()) {
    result.time_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    return result;
  }

  std::vector<NodeParameters> params(nodes.size());  // sized once: Ceres keeps pointers into it
  for (std::size_t k = 0; k < nodes.size(); ++k) {
    const Sim3& S = nodes[k].S_n_w;
    params[k].q = {S.q.x(), S.q.y(), S.q.z(), S.q.w()};
    params[k].t = {S.t.x(), S.t.y(), S.t.z()};
    params[k].log_s[0] = std::log(S.s);
  }

  // Outlive the problem, which does not own them.
  using EdgeCost = ceres::AutoDiffCostFunction<EdgeResidual, 7, 4, 3, 1, 4, 3, 1>;
  std::vector<std::unique_ptr<EdgeCost>> costs;
  costs.reserve(edges.size());
  for (const PoseGraphEdge& edge : edges) {
    const Sim3& S = edge.S_i_j;  // the cost owns its functor
    costs.push_back(std::make_unique<EdgeCost>(new EdgeResidual{S.q, S.t, S.s, std::log(S.s), std::sqrt(edge.weight)}));
  }

  ceres::Problem::Options problem_options;
  problem_options.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::EigenQuaternionManifold quaternion_manifold;  // outlives the problem too
  ceres::AutoDiffManifold<WorldYawPlus, 4, 1> yaw_manifold(new WorldYawPlus{options.yaw_axis.normalized()});
  ceres::Problem problem(problem_options);
  for (std::size_t k = 0; k < nodes.size(); ++k) {
    if (!used[k]) continue;
    NodeParameters& p = params[k];
    problem.AddParameterBlock(p.q.data(), 4,
                              options.yaw_only ? static_cast<ceres::Manifold*>(&yaw_manifold) : &quaternion_manifold);
    problem.AddParameterBlock(p.t.data(), 3);
    problem.AddParameterBlock(p.log_s.data(), 1);
    if (nodes[k].fixed) {
      problem.SetParameterBlockConstant(p.q.data());
      problem.SetParameterBlockConstant(p.t.data());
    }
    if (nodes[k].fixed || options.fix_scale) problem.SetParameterBlockConstant(p.log_s.data());
  }
  for (std::size_t e = 0; e < edges.size(); ++e) {
    NodeParameters& a = params[ends[e].first];
    NodeParameters& b = params[ends[e].second];
    problem.AddResidualBlock(costs[e].get(), nullptr, a.q.data(), a.t.data(), a.log_s.data(), b.q.data(), b.t.data(),
                             b.log_s.data());
  }

  ceres::Solver::Options so;
  so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  so.max_num_iterations = options.max_iterations;
  so.num_threads = options.num_threads;
  so.logging_type = ceres::SILENT;
  so.minimizer_progress_to_stdout = false;
  // Sparse normal equations (7 unknowns per node, coupled along the edges); dense only as a fallback.
  so.linear_solver_type = ceres::IsSparseLinearAlgebraLibraryTypeAvailable(so.sparse_linear_algebra_library_type)
                              ? ceres::SPARSE_NORMAL_CHOLESKY
                              : ceres::DENSE_NORMAL_CHOLESKY;
  so.function_tolerance = 1e-14;
  so.gradient_tolerance = 1e-16;
  so.parameter_tolerance = 1e-14;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);

  for (std::size_t k = 0; k < nodes.size(); ++k) {
    if (!used[k] || nodes[k].fixed) continue;  // bit-exact copies of the input
    const NodeParameters& p = params[k];
    result.nodes[k].S_n_w = Sim3(Eigen::Map<const Eigen::Quaterniond>(p.q.data()),
                                 Eigen::Map<const Eigen::Vector3d>(p.t.data()), std::exp(p.log_s[0]));
  }
  result.iterations = static_cast<int>(summary.iterations.size()) - 1;
  result.initial_cost = summary.initial_cost;
  result.final_cost = summary.final_cost;
  result.time_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace orbatlas
