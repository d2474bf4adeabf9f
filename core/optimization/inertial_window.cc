#include "core/optimization/inertial_window.h"

#include <cmath>

#include <algorithm>
#include <limits>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "core/common/error.h"
#include "core/common/timestamp.h"
#include "core/map/inertial_chain.h"
#include "core/optimization/inertial_cost.h"

namespace orbatlas {
namespace {

std::size_t add_block(BundleProblem& lp, const double* values, int size, bool fixed) {
  BundleExtraBlock block;
  block.values = std::make_unique<double[]>(static_cast<std::size_t>(size));
  std::copy(values, values + size, block.values.get());
  block.size = size;
  block.fixed = fixed;
  lp.extra_blocks.push_back(std::move(block));
  return lp.extra_blocks.size() - 1;
}

// The IMU's world pose from the keyframe's camera pose in the problem.
Pose3 imu_pose(const BundleProblem& lp, std::size_t k, const Pose3& T_c_i) {
  return lp.poses[k].pose().inverse() * T_c_i;
}

// The IMU in the cameras of a chain's keyframes: its links' own (every link of
// one chain is one session's), else the map's settings' (links stored before
// the atlas kept theirs).
Pose3 chain_T_c_i(const std::vector<std::shared_ptr<KeyFrame>>& keyframes, const InertialWindowOptions& options) {
  for (std::size_t i = 1; i < keyframes.size(); ++i)
    if (const auto link = keyframes[i]->inertial_link(); link && link->T_c_i) return *link->T_c_i;
  return keyframes.back()->T_b_c().inverse() * options.T_b_i;
}

}  // namespace

void InertialWindowOptions::check() const {
  ORBATLAS_CHECK(temporal_keyframes >= 2,
                 "visual-inertial BA: temporal_keyframes must be >= 2, not " << temporal_keyframes);
  ORBATLAS_CHECK(gravity_w.allFinite() && gravity_w.norm() > 0.0, "visual-inertial BA: gravity must be finite, not 0");
  ORBATLAS_CHECK(std::isfinite(huber) && huber >= 0.0, "visual-inertial BA: huber must be >= 0, not " << huber);
  ORBATLAS_CHECK(scale.gyro.allFinite() && scale.accel.allFinite() && scale.gyro.cwiseAbs().maxCoeff() < 0.1 &&
                     scale.accel.cwiseAbs().maxCoeff() < 0.1,
                 "visual-inertial BA: the IMU scale correction must be finite and under 10 % per axis");
  ORBATLAS_CHECK(std::isfinite(scale_sigma) && scale_sigma >= 0.0 && scale_sigma < 0.1,
                 "visual-inertial BA: scale_sigma must be in [0, 0.1), not " << scale_sigma);
}

InertialChainWindow inertial_chain_window(const std::shared_ptr<KeyFrame>& current,
                                          const InertialWindowOptions& options) {
  InertialChainWindow w;
  w.keyframes = inertial_chain(current, options.temporal_keyframes + 1);
  if (w.keyframes.size() > options.temporal_keyframes) {
    if (w.keyframes.front()->imu_state())
      w.anchored = true;
    else
      w.keyframes.erase(w.keyframes.begin());
  }
  return w;
}

InertialWindow add_inertial_window(BundleProblem& lp, const InertialChainWindow& chain,
                                   const InertialWindowOptions& options) {
  options.check();
  InertialWindow w;
  w.keyframes = chain.keyframes;
  w.anchored = chain.anchored && w.keyframes.size() >= 2;
  if (w.keyframes.size() < 2) return w;
  const Pose3 T_c_i = chain_T_c_i(w.keyframes, options);

  // Every keyframe first: adding one may move the pose storage.
  for (const auto& kf : w.keyframes) w.index.push_back(bundle_keyframe_index(lp, kf));
  if (w.anchored) lp.fixed[w.index.front()] = 1;

  const std::size_t n = w.keyframes.size();
  std::vector<Pose3> T_w_i(n);
  for (std::size_t i = 0; i < n; ++i) T_w_i[i] = imu_pose(lp, w.index[i], T_c_i);
  for (std::size_t i = 0; i < n; ++i) {
    const KeyFrame& kf = *w.keyframes[i];
    Eigen::Vector3d v_w;
    ImuBias bias = options.map_bias;
    if (const auto state = kf.imu_state()) {
      v_w = T_w_i[i].q.normalized() * state->v_i;
      bias = state->bias;
    } else {
      // The velocity the neighbours' positions imply.
      const std::size_t a = i > 0 ? i - 1 : i, b = i + 1 < n ? i + 1 : i;
      const double dt = ns_to_s(w.keyframes[b]->timestamp_ns() - w.keyframes[a]->timestamp_ns());
      v_w = dt > 0.0 ? Eigen::Vector3d((T_w_i[b].t - T_w_i[a].t) / dt) : Eigen::Vector3d::Zero();
    }
    double b6[6];
    std::copy(bias.gyro.data(), bias.gyro.data() + 3, b6);
    std::copy(bias.accel.data(), bias.accel.data() + 3, b6 + 3);
    const bool fixed = w.anchored && i == 0;
    w.velocity.push_back(add_block(lp, v_w.data(), 3, fixed));
    w.bias.push_back(add_block(lp, b6, 6, fixed));
  }

  // The scale correction: one block for the window's IMU, free under its
  // prior when estimated, held when only applied; none when there is none.
  w.has_scale = options.scale_sigma > 0.0 || options.scale != ImuScaleCorrection{};
  double s6[6];
  std::copy(options.scale.gyro.data(), options.scale.gyro.data() + 3, s6);
  std::copy(options.scale.accel.data(), options.scale.accel.data() + 3, s6 + 3);
  if (w.has_scale) w.scale = add_block(lp, s6, 6, options.scale_sigma <= 0.0);
  if (options.scale_sigma > 0.0) {
    BundleExtraTerm prior;
    prior.cost = make_diagonal_prior(Eigen::Map<const Eigen::Matrix<double, 6, 1>>(s6),
                                     Eigen::Matrix<double, 6, 1>::Constant(options.scale_sigma));
    prior.blocks = {lp.extra_blocks[w.scale].values.get()};
    lp.extra_terms.push_back(std::move(prior));
  }
  double* scale = w.has_scale ? lp.extra_blocks[w.scale].values.get() : nullptr;

  for (std::size_t i = 1; i < n; ++i) {
    const auto link = w.keyframes[i]->inertial_link();
    ORBATLAS_CHECK(link && link->from_previous && link->previous_id == w.keyframes[i - 1]->id(),
                   "visual-inertial BA: keyframe " << w.keyframes[i]->id() << " is not linked to keyframe "
                                                   << w.keyframes[i - 1]->id());
    const std::size_t a = w.index[i - 1], b = w.index[i];
    double* va = lp.extra_blocks[w.velocity[i - 1]].values.get();
    double* vb = lp.extra_blocks[w.velocity[i]].values.get();
    double* ba = lp.extra_blocks[w.bias[i - 1]].values.get();
    double* bb = lp.extra_blocks[w.bias[i]].values.get();
    BundleExtraTerm inertial;
    inertial.blocks = {
        lp.poses[a].q.data(), lp.poses[a].t.data(), va, lp.poses[b].q.data(), lp.poses[b].t.data(), vb, ba};
    if (scale) {
      inertial.cost = make_scaled_inertial_cost(link->from_previous, T_c_i, options.gravity_w);
      inertial.blocks.push_back(scale);
    } else {
      inertial.cost = make_inertial_cost(link->from_previous, T_c_i, options.gravity_w);
    }
    inertial.keyframes = {a, b};
    inertial.huber = options.huber;
    w.inertial_terms.push_back(lp.extra_terms.size());
    lp.extra_terms.push_back(std::move(inertial));
    BundleExtraTerm walk;
    walk.cost = make_bias_walk_cost(link->from_previous->noise(), link->from_previous->dt());
    walk.blocks = {ba, bb};
    lp.extra_terms.push_back(std::move(walk));
  }
  return w;
}

std::vector<double> inertial_window_chi2(const BundleProblem& lp, const InertialWindow& window) {
  std::vector<double> chi2;
  for (const std::size_t t : window.inertial_terms) {
    const BundleExtraTerm& term = lp.extra_terms[t];
    Eigen::Matrix<double, 9, 1> r;
    const bool ok = term.cost->num_residuals() == 9 && term.cost->Evaluate(term.blocks.data(), r.data(), nullptr);
    chi2.push_back(ok ? r.squaredNorm() : std::numeric_limits<double>::infinity());
  }
  return chi2;
}

std::vector<std::pair<std::shared_ptr<KeyFrame>, KeyFrame::ImuState>> inertial_window_states(
    const BundleProblem& lp, const InertialWindow& window, const InertialWindowOptions& options) {
  std::vector<std::pair<std::shared_ptr<KeyFrame>, KeyFrame::ImuState>> states;
  if (window.keyframes.size() < 2) return states;
  const Pose3 T_c_i = chain_T_c_i(window.keyframes, options);
  for (std::size_t i = window.anchored ? 1 : 0; i < window.keyframes.size(); ++i) {
    const Eigen::Map<const Eigen::Vector3d> v_w(lp.extra_blocks[window.velocity[i]].values.get());
    const double* b = lp.extra_blocks[window.bias[i]].values.get();
    KeyFrame::ImuState state;
    state.v_i = imu_pose(lp, window.index[i], T_c_i).q.normalized().conjugate() * v_w;
    state.bias.gyro = Eigen::Vector3d(b[0], b[1], b[2]);
    state.bias.accel = Eigen::Vector3d(b[3], b[4], b[5]);
    if (state.v_i.allFinite() && state.bias.gyro.allFinite() && state.bias.accel.allFinite())
      states.emplace_back(window.keyframes[i], state);
  }
  return states;
}

ImuScaleCorrection inertial_window_scale(const BundleProblem& lp, const InertialWindow& window,
                                         const InertialWindowOptions& options) {
  if (!window.has_scale) return options.scale;
  const double* s = lp.extra_blocks[window.scale].values.get();
  ImuScaleCorrection out;
  out.gyro = Eigen::Vector3d(s[0], s[1], s[2]);
  out.accel = Eigen::Vector3d(s[3], s[4], s[5]);
  return out.gyro.allFinite() && out.accel.allFinite() ? out : options.scale;
}

ImuScaleInformation inertial_window_scale_information(const BundleProblem& lp, const InertialWindow& window) {
  using Matrix96 = Eigen::Matrix<double, 9, 6, Eigen::RowMajor>;
  ImuScaleInformation ss = ImuScaleInformation::Zero(), sb = ImuScaleInformation::Zero(),
                      bb = ImuScaleInformation::Zero();
  if (!window.has_scale) return ss;
  for (const std::size_t t : window.inertial_terms) {
    const BundleExtraTerm& term = lp.extra_terms[t];
    if (term.blocks.size() != 8) continue;
    Eigen::Matrix<double, 9, 1> r;
    Matrix96 J_bias, J_scale;
    double* jacobians[8] = {nullptr, nullptr, nullptr, nullptr, nullptr, nullptr, J_bias.data(), J_scale.data()};
    if (!term.cost->Evaluate(term.blocks.data(), r.data(), jacobians) || !J_bias.allFinite() || !J_scale.allFinite())
      continue;
    ss += J_scale.transpose() * J_scale;
    sb += J_scale.transpose() * J_bias;
    bb += J_bias.transpose() * J_bias;
  }
  // The biases eliminated (a tiny ridge for an axis no term moves).
  const ImuScaleInformation bb_ridge = bb + 1e-9 * (1.0 + bb.diagonal().maxCoeff()) * ImuScaleInformation::Identity();
  ImuScaleInformation info = ss - sb * bb_ridge.ldlt().solve(sb.transpose());
  info = 0.5 * (info + info.transpose()).eval();
  // Rounding can leave it a little indefinite: clamp its eigenvalues at 0.
  const Eigen::SelfAdjointEigenSolver<ImuScaleInformation> eig(info);
  if (eig.info() != Eigen::Success) return ImuScaleInformation::Zero();
  const Eigen::Matrix<double, 6, 1> values = eig.eigenvalues().cwiseMax(0.0);
  return eig.eigenvectors() * values.asDiagonal() * eig.eigenvectors().transpose();
}

void write_back_inertial_window(const BundleProblem& lp, const InertialWindow& window,
                                const InertialWindowOptions& options) {
  for (const auto& [kf, state] : inertial_window_states(lp, window, options))
    if (!kf->is_bad()) kf->set_imu_state(state);
}

}  // namespace orbatlas
