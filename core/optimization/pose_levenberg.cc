#include "core/optimization/pose_levenberg.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <limits>

#include <ceres/manifold.h>

namespace orbatlas {
namespace {

using Matrix6 = Eigen::Matrix<double, 6, 6>;
using Vector6 = Eigen::Matrix<double, 6, 1>;

struct Linearisation {
  double cost = 0.0;
  Matrix6 H = Matrix6::Zero();  // J^T W J in the tangent coordinates (rotation 3, translation 3)
  Vector6 g = Vector6::Zero();  // J^T W r
  bool ok = true;
};

// The cost, and with `jacobians` the reweighted normal equations, at `pose`.
Linearisation linearise(const std::vector<PoseTerm>& terms, const PoseParameters& pose, bool jacobians) {
  Linearisation out;
  const double* params[2] = {pose.q.data(), pose.t.data()};
  Eigen::Matrix<double, 4, 3, Eigen::RowMajor> plus;
  if (jacobians) ceres::EigenQuaternionManifold().PlusJacobian(pose.q.data(), plus.data());
  double r[3], jq[12], jt[9];
  double* jac[2] = {jq, jt};
  for (const PoseTerm& term : terms) {
    const int k = term.cost->num_residuals();
    if (!term.cost->Evaluate(params, r, jacobians ? jac : nullptr)) {
      out.ok = false;
      return out;
    }
    double s = 0.0;
    for (int i = 0; i < k; ++i) s += r[i] * r[i];
    double rho = s, weight = 1.0;
    if (term.huber > 0.0 && s > term.huber * term.huber) {
      const double root = std::sqrt(s);
      rho = 2.0 * term.huber * root - term.huber * term.huber;
      weight = term.huber / root;
    }
    out.cost += 0.5 * rho;
    if (!jacobians) continue;
    for (int i = 0; i < k; ++i) {
      Vector6 row;
      const Eigen::Map<const Eigen::Matrix<double, 1, 4>> dq(jq + 4 * i);
      row.head<3>() = (dq * plus).transpose();
      row.tail<3>() = Eigen::Map<const Eigen::Vector3d>(jt + 3 * i);
      // The upper triangle of weight * row * row^T, as Eigen's rankUpdate sums
      // it (the same products in the same order) without its general-size
      // kernel's overhead (1.8 % of a loaded server's samples).
      for (int j = 0; j < 6; ++j) {
        const double scaled = weight * row[j];
        for (int a = 0; a <= j; ++a) out.H(a, j) += scaled * row[a];
      }
      out.g += weight * r[i] * row;
    }
  }
  if (jacobians) out.H = out.H.selfadjointView<Eigen::Upper>();
  return out;
}

PoseParameters plus(const PoseParameters& x, const Vector6& delta) {
  PoseParameters out;
  ceres::EigenQuaternionManifold().Plus(x.q.data(), delta.data(), out.q.data());
  for (int i = 0; i < 3; ++i) out.t[static_cast<std::size_t>(i)] = x.t[static_cast<std::size_t>(i)] + delta[3 + i];
  return out;
}

double state_norm(const PoseParameters& x) {
  double s = 0.0;
  for (const double v : x.q) s += v * v;
  for (const double v : x.t) s += v * v;
  return std::sqrt(s);
}

}  // namespace

PoseLevenbergResult solve_pose_levenberg(const std::vector<PoseTerm>& terms, PoseParameters& pose,
                                         const PoseLevenbergOptions& options) {
  PoseLevenbergResult result;
  Linearisation at = linearise(terms, pose, true);
  result.initial_cost = result.final_cost = at.cost;
  if (!at.ok) {
    result.usable = false;
    return result;
  }
  double radius = 1e4, decrease_factor = 2.0;
  for (int it = 0; it < options.max_iterations; ++it) {
    if (at.g.cwiseAbs().maxCoeff() <= options.gradient_tolerance) break;
    Matrix6 A = at.H;
    for (int i = 0; i < 6; ++i) A(i, i) += std::clamp(at.H(i, i), 1e-6, 1e32) / radius;
    const Vector6 step = A.ldlt().solve(-at.g);
    ++result.iterations;
    if (!step.allFinite()) break;
    if (step.norm() <= options.parameter_tolerance * (state_norm(pose) + options.parameter_tolerance)) break;
    const PoseParameters candidate = plus(pose, step);
    const Linearisation next = linearise(terms, candidate, false);
    const double model_decrease = -(at.g.dot(step) + 0.5 * step.dot(at.H * step));
    const double gain = next.ok && model_decrease > 0.0 ? (at.cost - next.cost) / model_decrease
                                                        : -std::numeric_limits<double>::infinity();
    if (gain > 1e-3) {
      const double decrease = at.cost - next.cost;
      pose = candidate;
      radius = radius / std::max(1.0 / 3.0, 1.0 - std::pow(2.0 * gain - 1.0, 3));
      decrease_factor = 2.0;
      if (decrease <= options.function_tolerance * at.cost) {
        at.cost = next.cost;
        break;
      }
      at = linearise(terms, pose, true);
      if (!at.ok) break;  // cannot happen: the cost evaluated there
    } else {
      radius /= decrease_factor;
      decrease_factor *= 2.0;
      if (radius < 1e-32) break;
    }
  }
  result.final_cost = at.cost;
  return result;
}

}  // namespace orbatlas
