#include "core/optimization/bundle_levenberg.h"

#include <ceres/manifold.h>

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/LU>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <optional>
#include <vector>

#include "core/optimization/bundle_layout.h"

namespace orbatlas {
namespace {

using Matrix6 = Eigen::Matrix<double, 6, 6>;
using Vector6 = Eigen::Matrix<double, 6, 1>;
using Matrix36 = Eigen::Matrix<double, 3, 6>;
using Matrix63 = Eigen::Matrix<double, 6, 3>;
constexpr int kNone = kNoBundleVar;
constexpr double kMinDiagonal = 1e-6, kMaxDiagonal = 1e32;  // Ceres' LM diagonal clamp
constexpr double kMaxRadius = 1e16, kMinRadius = 1e-32;
constexpr double kMinRelativeDecrease = 1e-3;

// Huber's rho(s) and the weight rho'(s) that Ceres' corrector applies (its
// second derivative is negative beyond the width: no curvature correction).
struct Robust {
  double rho = 0.0, weight = 1.0;
};
Robust robust_of(double s, double width) {
  if (width <= 0.0 || s <= width * width) return {s, 1.0};
  const double root = std::sqrt(s);
  return {2.0 * width * root - width * width, width / root};
}

double width_of(const BundleEdge& e, bool robust, const BundleSettings& settings) {
  if (!robust) return 0.0;
  return e.stereo ? settings.huber_stereo : settings.huber_mono;
}

struct EdgeJacobian {
  Matrix36 Jc = Matrix36::Zero();  // d r / d (pose tangent: rotation 3, translation 3); zero for a fixed pose
  Eigen::Matrix3d Jx = Eigen::Matrix3d::Zero();
  Eigen::Vector3d r = Eigen::Vector3d::Zero();  // rows past the residual's own are zero
  double weight = 1.0;
  Matrix63 W = Matrix63::Zero();  // weight Jc^T Jx
};

using RowMajorMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

struct TermJacobian {
  Eigen::VectorXd r;
  std::vector<Eigen::MatrixXd> J;  // per block: d r / d (its unknowns); empty for a constant block
  double weight = 1.0;
};

// The normal equations at the current estimates, per block.
struct Linearisation {
  double cost = 0.0;
  double max_gradient = 0.0;
  std::vector<EdgeJacobian> edges;  // per entry of BundleLayout::edges
  std::vector<Matrix6> U;           // per free pose: sum weight Jc^T Jc over the edges
  std::vector<Vector6> a;           // per free pose: sum weight J^T r (edges and extra terms)
  std::vector<Eigen::Matrix3d> V;   // per point: sum weight Jx^T Jx
  std::vector<Eigen::Vector3d> b;   // per point: sum weight Jx^T r
  std::vector<TermJacobian> terms;  // per extra term
  Eigen::VectorXd c;                // per extra unknown (past the poses): sum weight J^T r
};

// An extra term's residual (and, when `jacobians` is given, its Jacobians per
// block as Ceres lays them out) at the current estimates; false when it
// cannot be evaluated.
bool evaluate_term(const BundleExtraTerm& term, Eigen::VectorXd& r, double** jacobians) {
  r.resize(term.cost->num_residuals());
  return term.cost->Evaluate(term.blocks.data(), r.data(), jacobians);
}

// The extra terms' part of the normal equations.
bool linearise_terms(const BundleProblem& lp, const BundleLayout& l,
                     const std::vector<Eigen::Matrix<double, 4, 3, Eigen::RowMajor>>& plus, Linearisation& out) {
  out.terms.resize(lp.extra_terms.size());
  out.c.setZero(l.dim - l.pose_dim());
  std::vector<std::vector<double>> raw;
  std::vector<double*> jacobians;
  for (std::size_t t = 0; t < lp.extra_terms.size(); ++t) {
    const BundleExtraTerm& term = lp.extra_terms[t];
    const std::vector<BundleTermBlock>& blocks = l.terms[t];
    const int rows = term.cost->num_residuals();
    raw.resize(blocks.size());
    jacobians.assign(blocks.size(), nullptr);
    for (std::size_t k = 0; k < blocks.size(); ++k) {
      if (blocks[k].offset == kNone) continue;
      raw[k].resize(static_cast<std::size_t>(rows * blocks[k].global));
      jacobians[k] = raw[k].data();
    }
    TermJacobian& tj = out.terms[t];
    if (!evaluate_term(term, tj.r, jacobians.data())) return false;
    const Robust rb = robust_of(tj.r.squaredNorm(), term.huber);
    out.cost += 0.5 * rb.rho;
    tj.weight = rb.weight;
    tj.J.resize(blocks.size());
    for (std::size_t k = 0; k < blocks.size(); ++k) {
      const BundleTermBlock& tb = blocks[k];
      if (tb.offset == kNone) {
        tj.J[k].resize(0, 0);
        continue;
      }
      const Eigen::Map<const RowMajorMatrix> global(raw[k].data(), rows, tb.global);
      if (tb.rotation_of != kNone)
        tj.J[k].noalias() = global * plus[static_cast<std::size_t>(tb.rotation_of)];
      else
        tj.J[k] = global;
      const Eigen::VectorXd g = rb.weight * tj.J[k].transpose() * tj.r;
      if (tb.offset < l.pose_dim())
        out.a[static_cast<std::size_t>(tb.offset / 6)].segment(tb.offset % 6, tb.size) += g;
      else
        out.c.segment(tb.offset - l.pose_dim(), tb.size) += g;
    }
  }
  return true;
}

bool linearise(const BundleProblem& lp, const BundleLayout& l, bool robust, const BundleSettings& settings,
               Linearisation& out) {
  const std::size_t poses = l.free_keyframes.size(), points = l.points.size();
  out.cost = 0.0;
  out.U.assign(poses, Matrix6::Zero());
  out.a.assign(poses, Vector6::Zero());
  out.V.assign(points, Eigen::Matrix3d::Zero());
  out.b.assign(points, Eigen::Vector3d::Zero());
  out.edges.resize(l.edges.size());
  std::vector<Eigen::Matrix<double, 4, 3, Eigen::RowMajor>> plus(poses);
  const ceres::EigenQuaternionManifold manifold;
  for (std::size_t f = 0; f < poses; ++f) manifold.PlusJacobian(lp.poses[l.free_keyframes[f]].q.data(), plus[f].data());

  double r[3], jq[12], jt[9], jx[9];
  for (std::size_t v = 0; v < points; ++v) {
    for (std::size_t n = l.point_begin[v]; n < l.point_begin[v + 1]; ++n) {
      const BundleEdge& e = lp.edges[l.edges[n]];
      const int f = l.edge_pose[n];
      const std::array<const double*, 3> params = lp.parameters(e);
      double* jacobians[3] = {f == kNone ? nullptr : jq, f == kNone ? nullptr : jt, jx};
      if (!e.cost->Evaluate(params.data(), r, jacobians)) return false;
      const int rows = e.cost->num_residuals();
      EdgeJacobian& ej = out.edges[n];
      ej.r.setZero();
      ej.Jx.setZero();
      ej.Jc.setZero();
      for (int i = 0; i < rows; ++i) {
        ej.r[i] = r[i];
        ej.Jx.row(i) = Eigen::Map<const Eigen::RowVector3d>(jx + 3 * i);
      }
      const Robust rb = robust_of(ej.r.squaredNorm(), width_of(e, robust, settings));
      out.cost += 0.5 * rb.rho;
      ej.weight = rb.weight;
      out.V[v].noalias() += rb.weight * ej.Jx.transpose() * ej.Jx;
      out.b[v].noalias() += rb.weight * ej.Jx.transpose() * ej.r;
      if (f == kNone) continue;
      const auto fu = static_cast<std::size_t>(f);
      for (int i = 0; i < rows; ++i) {
        ej.Jc.row(i).head<3>() = Eigen::Map<const Eigen::Matrix<double, 1, 4>>(jq + 4 * i) * plus[fu];
        ej.Jc.row(i).tail<3>() = Eigen::Map<const Eigen::RowVector3d>(jt + 3 * i);
      }
      out.U[fu].noalias() += rb.weight * ej.Jc.transpose() * ej.Jc;
      out.a[fu].noalias() += rb.weight * ej.Jc.transpose() * ej.r;
      ej.W.noalias() = rb.weight * ej.Jc.transpose() * ej.Jx;
    }
  }
  if (!linearise_terms(lp, l, plus, out)) return false;
  out.max_gradient = out.c.size() > 0 ? out.c.cwiseAbs().maxCoeff() : 0.0;
  for (const Vector6& g : out.a) out.max_gradient = std::max(out.max_gradient, g.cwiseAbs().maxCoeff());
  for (const Eigen::Vector3d& g : out.b) out.max_gradient = std::max(out.max_gradient, g.cwiseAbs().maxCoeff());
  return true;
}

// The cost alone; nullopt when an observation cannot be evaluated.
std::optional<double> cost_at(const BundleProblem& lp, const BundleLayout& l, bool robust,
                              const BundleSettings& settings) {
  double cost = 0.0, r[3];
  for (const std::size_t i : l.edges) {
    const BundleEdge& e = lp.edges[i];
    const std::array<const double*, 3> params = lp.parameters(e);
    if (!e.cost->Evaluate(params.data(), r, nullptr)) return std::nullopt;
    double s = 0.0;
    for (int k = 0; k < e.cost->num_residuals(); ++k) s += r[k] * r[k];
    cost += 0.5 * robust_of(s, width_of(e, robust, settings)).rho;
  }
  Eigen::VectorXd term_r;
  for (const BundleExtraTerm& term : lp.extra_terms) {
    if (!evaluate_term(term, term_r, nullptr)) return std::nullopt;
    cost += 0.5 * robust_of(term_r.squaredNorm(), term.huber).rho;
  }
  return cost;
}

template <int N>
Eigen::Matrix<double, N, N> damped(Eigen::Matrix<double, N, N> m, double radius) {
  for (int i = 0; i < N; ++i) m(i, i) += std::clamp(m(i, i), kMinDiagonal, kMaxDiagonal) / radius;
  return m;
}

struct Step {
  Eigen::VectorXd reduced;  // the poses (6 each), then the extra blocks (BundleLayout::dim)
  std::vector<Eigen::Vector3d> points;
  Vector6 pose(std::size_t f) const { return reduced.segment<6>(static_cast<Eigen::Index>(6 * f)); }
};

// The buffers of the linear solves, kept over a stage's iterations (a reduced
// system of 100 keyframes is 2.9 MB: allocated once, not per iteration).
struct Workspace {
  Eigen::MatrixXd S;  // the reduced system over the free poses (upper block triangle), factored in place
  Eigen::VectorXd rhs;
  std::vector<Eigen::Matrix3d> V_inv;  // per point
  std::vector<Matrix63> T;             // per edge of the point being eliminated: W V^-1
};

// Solves (H + D / radius) step = -g with the points eliminated; false when
// the damped system is not positive definite.
bool solve_step(const Linearisation& at, const BundleLayout& l, double radius, Workspace& ws, Step& step) {
  const std::size_t poses = l.free_keyframes.size(), points = l.points.size();
  const Eigen::Index dim = l.dim;
  ws.S.setZero(dim, dim);
  ws.rhs.resize(dim);
  for (std::size_t f = 0; f < poses; ++f) {
    const auto o = static_cast<Eigen::Index>(6 * f);
    ws.S.block<6, 6>(o, o) = at.U[f];
    ws.rhs.segment<6>(o) = -at.a[f];
  }
  ws.rhs.tail(dim - l.pose_dim()) = -at.c;
  // The extra terms' blocks (the upper triangle: a pair's block above the
  // diagonal, a block with itself whole).
  for (std::size_t t = 0; t < at.terms.size(); ++t) {
    const TermJacobian& tj = at.terms[t];
    const std::vector<BundleTermBlock>& blocks = l.terms[t];
    for (std::size_t i = 0; i < blocks.size(); ++i) {
      if (blocks[i].offset == kNone) continue;
      for (std::size_t j = 0; j < blocks.size(); ++j) {
        if (blocks[j].offset == kNone || blocks[j].offset < blocks[i].offset) continue;
        ws.S.block(blocks[i].offset, blocks[j].offset, blocks[i].size, blocks[j].size).noalias() +=
            tj.weight * tj.J[i].transpose() * tj.J[j];
      }
    }
  }
  // Damping: the clamped diagonal of J^T W J (edges and extra terms) over the radius.
  for (Eigen::Index i = 0; i < dim; ++i) ws.S(i, i) += std::clamp(ws.S(i, i), kMinDiagonal, kMaxDiagonal) / radius;
  ws.V_inv.resize(points);
  for (std::size_t v = 0; v < points; ++v) {
    ws.V_inv[v] = damped<3>(at.V[v], radius).inverse();
    if (!ws.V_inv[v].allFinite()) return false;
    const std::size_t begin = l.point_begin[v], end = l.point_begin[v + 1];
    ws.T.resize(std::max(ws.T.size(), end - begin));
    for (std::size_t n = begin; n < end; ++n) {
      const int f = l.edge_pose[n];
      if (f == kNone) continue;
      ws.T[n - begin].noalias() = at.edges[n].W * ws.V_inv[v];
      ws.rhs.segment<6>(6 * f).noalias() += ws.T[n - begin] * at.b[v];
    }
    for (std::size_t n1 = begin; n1 < end; ++n1) {
      const int f1 = l.edge_pose[n1];
      if (f1 == kNone) continue;
      for (std::size_t n2 = begin; n2 < end; ++n2) {
        const int f2 = l.edge_pose[n2];
        if (f2 == kNone || f2 < f1) continue;  // the upper triangle of blocks (whole diagonal blocks)
        ws.S.block<6, 6>(6 * f1, 6 * f2).noalias() -= ws.T[n1 - begin] * at.edges[n2].W.transpose();
      }
    }
  }
  if (dim > 0) {
    const Eigen::LLT<Eigen::Ref<Eigen::MatrixXd>, Eigen::Upper> llt(ws.S);  // in place
    if (llt.info() != Eigen::Success) return false;
    llt.solveInPlace(ws.rhs);
    if (!ws.rhs.allFinite()) return false;
  }
  step.reduced = ws.rhs;
  step.points.resize(points);
  for (std::size_t v = 0; v < points; ++v) {
    Eigen::Vector3d x = -at.b[v];
    for (std::size_t n = l.point_begin[v]; n < l.point_begin[v + 1]; ++n)
      if (const int f = l.edge_pose[n]; f != kNone)
        x.noalias() -= at.edges[n].W.transpose() * step.pose(static_cast<std::size_t>(f));
    step.points[v] = ws.V_inv[v] * x;
    if (!step.points[v].allFinite()) return false;
  }
  return true;
}

// The decrease of the linearised (reweighted) cost along `step`.
double model_decrease(const Linearisation& at, const BundleLayout& l, const Step& step) {
  double decrease = 0.0;
  for (std::size_t v = 0; v < l.points.size(); ++v) {
    for (std::size_t n = l.point_begin[v]; n < l.point_begin[v + 1]; ++n) {
      const EdgeJacobian& ej = at.edges[n];
      Eigen::Vector3d change = ej.Jx * step.points[v];
      if (const int f = l.edge_pose[n]; f != kNone) change.noalias() += ej.Jc * step.pose(static_cast<std::size_t>(f));
      decrease -= ej.weight * (ej.r.dot(change) + 0.5 * change.squaredNorm());
    }
  }
  for (std::size_t t = 0; t < at.terms.size(); ++t) {
    const TermJacobian& tj = at.terms[t];
    Eigen::VectorXd change = Eigen::VectorXd::Zero(tj.r.size());
    for (std::size_t k = 0; k < l.terms[t].size(); ++k) {
      const BundleTermBlock& tb = l.terms[t][k];
      if (tb.offset != kNone) change.noalias() += tj.J[k] * step.reduced.segment(tb.offset, tb.size);
    }
    decrease -= tj.weight * (tj.r.dot(change) + 0.5 * change.squaredNorm());
  }
  return decrease;
}

double squared_norm(const Step& step) {
  double s = step.reduced.squaredNorm();
  for (const Eigen::Vector3d& d : step.points) s += d.squaredNorm();
  return s;
}

double state_norm(const BundleProblem& lp, const BundleLayout& l) {
  double s = 0.0;
  for (const std::size_t k : l.free_keyframes) {
    for (const double x : lp.poses[k].q) s += x * x;
    for (const double x : lp.poses[k].t) s += x * x;
  }
  for (const std::size_t j : l.points)
    for (const double x : lp.positions[j]) s += x * x;
  for (const std::size_t e : l.free_extras) {
    const BundleExtraBlock& b = lp.extra_blocks[e];
    for (int i = 0; i < b.size; ++i) s += b.values[static_cast<std::size_t>(i)] * b.values[static_cast<std::size_t>(i)];
  }
  return std::sqrt(s);
}

void apply(BundleProblem& lp, const BundleLayout& l, const Step& step) {
  const ceres::EigenQuaternionManifold manifold;
  for (std::size_t f = 0; f < l.free_keyframes.size(); ++f) {
    PoseParameters& pose = lp.poses[l.free_keyframes[f]];
    std::array<double, 4> q{};
    const Vector6 d = step.pose(f);
    manifold.Plus(pose.q.data(), d.data(), q.data());
    pose.q = q;
    for (int i = 0; i < 3; ++i) pose.t[static_cast<std::size_t>(i)] += d[3 + i];
  }
  for (std::size_t e = 0; e < l.free_extras.size(); ++e) {
    BundleExtraBlock& b = lp.extra_blocks[l.free_extras[e]];
    for (int i = 0; i < b.size; ++i) b.values[static_cast<std::size_t>(i)] += step.reduced[l.extra_offset[e] + i];
  }
  for (std::size_t v = 0; v < l.points.size(); ++v)
    for (int i = 0; i < 3; ++i) lp.positions[l.points[v]][static_cast<std::size_t>(i)] += step.points[v][i];
}

}  // namespace

BundleLevenbergResult solve_bundle_levenberg(BundleProblem& lp, bool robust, const BundleSettings& settings,
                                             const BundleLevenbergOptions& options) {
  BundleLevenbergResult result;
  const BundleLayout l = bundle_layout_of(lp);
  if (l.edges.empty() && lp.extra_terms.empty()) return result;
  Linearisation at;
  if (!linearise(lp, l, robust, settings, at)) {
    result.usable = false;
    return result;
  }
  result.initial_cost = result.final_cost = at.cost;
  double radius = options.initial_radius, decrease_factor = 2.0;
  Step step;
  Workspace workspace;
  std::vector<PoseParameters> saved_poses;
  std::vector<std::array<double, 3>> saved_positions;
  std::vector<std::vector<double>> saved_extras(l.free_extras.size());
  const auto save_extras = [&] {
    for (std::size_t e = 0; e < l.free_extras.size(); ++e) {
      const BundleExtraBlock& b = lp.extra_blocks[l.free_extras[e]];
      saved_extras[e].assign(b.values.get(), b.values.get() + b.size);
    }
  };
  const auto restore_extras = [&] {
    for (std::size_t e = 0; e < l.free_extras.size(); ++e)
      std::copy(saved_extras[e].begin(), saved_extras[e].end(), lp.extra_blocks[l.free_extras[e]].values.get());
  };
  for (int it = 0; it < options.max_iterations; ++it) {
    if (options.stop != nullptr && options.stop->load(std::memory_order_relaxed)) {
      result.stopped = true;
      break;
    }
    if (at.max_gradient <= options.gradient_tolerance) break;
    ++result.iterations;
    if (!solve_step(at, l, radius, workspace, step)) {
      radius /= decrease_factor;
      decrease_factor *= 2.0;
      if (radius < kMinRadius) break;
      continue;
    }
    const double x_norm = state_norm(lp, l);
    if (std::sqrt(squared_norm(step)) <= options.parameter_tolerance * (x_norm + options.parameter_tolerance)) break;
    const double predicted = model_decrease(at, l, step);
    saved_poses = lp.poses;
    saved_positions = lp.positions;
    save_extras();
    apply(lp, l, step);
    const std::optional<double> cost = cost_at(lp, l, robust, settings);
    const double gain =
        cost && predicted > 0.0 ? (at.cost - *cost) / predicted : -std::numeric_limits<double>::infinity();
    if (gain > kMinRelativeDecrease) {
      const double decrease = at.cost - *cost;
      radius = std::min(kMaxRadius, radius / std::max(1.0 / 3.0, 1.0 - std::pow(2.0 * gain - 1.0, 3)));
      decrease_factor = 2.0;
      if (decrease <= options.function_tolerance * at.cost) {
        at.cost = *cost;
        break;
      }
      if (!linearise(lp, l, robust, settings, at)) {  // cannot happen: the cost evaluated there
        at.cost = *cost;                              // the step is kept; the solve ends
        break;
      }
    } else {
      lp.poses = saved_poses;
      lp.positions = saved_positions;
      restore_extras();
      radius /= decrease_factor;
      decrease_factor *= 2.0;
      if (radius < kMinRadius) break;
    }
  }
  result.final_cost = at.cost;
  return result;
}

}  // namespace orbatlas
