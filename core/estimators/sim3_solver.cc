#include "core/estimators/sim3_solver.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "core/common/error.h"
#include "core/estimators/absolute_orientation.h"

namespace orbatlas {

void Sim3SolverOptions::check() const {
  ORBATLAS_CHECK(probability > 0.0 && probability < 1.0,
                 "Sim3Solver: probability must be in (0, 1), not " << probability);
  ORBATLAS_CHECK(min_inliers >= 0, "Sim3Solver: min_inliers must be >= 0, not " << min_inliers);
  ORBATLAS_CHECK(max_iterations >= 0, "Sim3Solver: max_iterations must be >= 0, not " << max_iterations);
  ORBATLAS_CHECK(chi2 > 0.0, "Sim3Solver: chi2 must be > 0, not " << chi2);
}

Sim3Solver::Sim3Solver(std::vector<Sim3Match> matches, const Camera& camera1, const Camera& camera2,
                       const Sim3SolverOptions& options)
    : matches_(std::move(matches)), camera1_(&camera1), camera2_(&camera2), options_(options), rng_(options.seed) {
  options_.check();
  for (std::size_t i = 0; i < matches_.size(); ++i) {
    const Sim3Match& m = matches_[i];
    ORBATLAS_CHECK(m.level_sigma2_1 > 0.0 && std::isfinite(m.level_sigma2_1) && m.level_sigma2_2 > 0.0 &&
                       std::isfinite(m.level_sigma2_2),
                   "Sim3Solver: match " << i << " has level sigma2 " << m.level_sigma2_1 << " / " << m.level_sigma2_2);
  }
  const int n = static_cast<int>(matches_.size());
  // Nothing to search when no sample can be drawn or no hypothesis could reach min_inliers.
  needed_ = (n < 3 || n < options_.min_inliers) ? 0 : options_.max_iterations;
  if (needed_ > 0) update_needed();
}

void Sim3Solver::update_needed() {
  const double n = static_cast<double>(matches_.size());
  // If the true inlier ratio were at least this, `probability` of the samples so
  // far would have contained an all-inlier one (ORB-SLAM uses min_inliers / n).
  const double ratio = static_cast<double>(std::max(best_count_, options_.min_inliers)) / n;
  const double p_good = ratio * ratio * ratio;
  int k = options_.max_iterations;
  if (p_good >= 1.0) {
    k = 1;
  } else if (p_good > 0.0) {
    const double wanted = std::ceil(std::log(1.0 - options_.probability) / std::log(1.0 - p_good));
    if (wanted < static_cast<double>(k)) k = std::max(1, static_cast<int>(wanted));
  }
  needed_ = std::min(options_.max_iterations, k);
}

bool Sim3Solver::inlier(const Sim3Match& m, const Sim3& S_1_2, const Sim3& S_2_1) const {
  Eigen::Vector2d uv;
  if (!camera1_->project(S_1_2 * m.p_c2, &uv)) return false;
  if ((uv - m.uv1).squaredNorm() >= options_.chi2 * m.level_sigma2_1) return false;
  if (!camera2_->project(S_2_1 * m.p_c1, &uv)) return false;
  return (uv - m.uv2).squaredNorm() < options_.chi2 * m.level_sigma2_2;
}

int Sim3Solver::classify(const Sim3& S_1_2, std::vector<std::uint8_t>* inliers) const {
  const Sim3 S_2_1 = S_1_2.inverse();
  inliers->assign(matches_.size(), 0);
  int count = 0;
  for (std::size_t i = 0; i < matches_.size(); ++i) {
    if (inlier(matches_[i], S_1_2, S_2_1)) {
      (*inliers)[i] = 1;
      ++count;
    }
  }
  return count;
}

bool Sim3Solver::iterate(int iterations) {
  const std::size_t n = matches_.size();
  std::vector<std::uint8_t> scratch;
  for (int k = 0; k < iterations && !finished(); ++k) {
    ++iterations_;
    std::uniform_int_distribution<std::size_t> pick(0, n - 1);
    std::array<std::size_t, 3> idx{};
    idx[0] = pick(rng_);
    do idx[1] = pick(rng_);
    while (idx[1] == idx[0]);
    do idx[2] = pick(rng_);
    while (idx[2] == idx[0] || idx[2] == idx[1]);
    const std::array<Eigen::Vector3d, 3> p1{matches_[idx[0]].p_c1, matches_[idx[1]].p_c1, matches_[idx[2]].p_c1};
    const std::array<Eigen::Vector3d, 3> p2{matches_[idx[0]].p_c2, matches_[idx[1]].p_c2, matches_[idx[2]].p_c2};
    const std::optional<Sim3> S = horn_absolute_orientation(p1, p2, !options_.fix_scale);
    if (!S) continue;  // collinear sample
    const int count = classify(*S, &scratch);
    if (count > best_count_) {
      best_count_ = count;
      best_ = *S;
      update_needed();
    }
  }
  return finished();
}

Sim3SolverResult Sim3Solver::result() const {
  Sim3SolverResult r;
  r.iterations = iterations_;
  r.inliers.assign(matches_.size(), 0);
  if (best_count_ == 0) return r;

  Sim3 S = best_;
  int count = classify(S, &r.inliers);
  // Refit on all inliers: the minimal sample carries its three matches' noise;
  // the least-squares fit on the consensus set may admit a few more inliers.
  std::vector<std::uint8_t> refit_inliers;
  std::vector<Eigen::Vector3d> p1, p2;
  for (int round = 0; round < 5; ++round) {
    p1.clear();
    p2.clear();
    for (std::size_t i = 0; i < matches_.size(); ++i) {
      if (!r.inliers[i]) continue;
      p1.push_back(matches_[i].p_c1);
      p2.push_back(matches_[i].p_c2);
    }
    if (p1.size() < 3) break;
    const std::optional<Sim3> refit = horn_absolute_orientation(p1, p2, !options_.fix_scale);
    if (!refit) break;
    const int refit_count = classify(*refit, &refit_inliers);
    if (refit_count < count) break;  // the 3D fit can be pulled by far, noisy points: keep the better score
    const bool grew = refit_count > count;
    S = *refit;
    r.inliers.swap(refit_inliers);
    count = refit_count;
    if (!grew) break;
  }
  r.S_1_2 = S;
  r.inlier_count = count;
  r.success = count >= options_.min_inliers;
  return r;
}

Sim3SolverResult solve_sim3_ransac(std::vector<Sim3Match> matches, const Camera& camera1, const Camera& camera2,
                                   const Sim3SolverOptions& options) {
  Sim3Solver solver(std::move(matches), camera1, camera2, options);
  solver.iterate(std::numeric_limits<int>::max());
  return solver.result();
}

}  // namespace orbatlas
