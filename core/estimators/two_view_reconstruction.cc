#include "core/estimators/two_view_reconstruction.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>

#include "core/common/error.h"
#include "core/geometry/triangulate.h"

namespace orbatlas {

void TwoViewOptions::check() const {
  ORBATLAS_CHECK(iterations >= 1, "two-view reconstruction: iterations must be >= 1, not " << iterations);
  ORBATLAS_CHECK(sigma_px > 0.0 && std::isfinite(sigma_px),
                 "two-view reconstruction: sigma_px must be > 0, not " << sigma_px);
  ORBATLAS_CHECK(focal_px > 0.0 && std::isfinite(focal_px),
                 "two-view reconstruction: focal_px must be > 0, not " << focal_px);
  ORBATLAS_CHECK(homography_ratio > 0.0 && homography_ratio < 1.0,
                 "two-view reconstruction: homography_ratio must be in (0, 1), not " << homography_ratio);
  ORBATLAS_CHECK(min_parallax_deg >= 0.0 && min_parallax_deg < 90.0,
                 "two-view reconstruction: min_parallax_deg must be in [0, 90), not " << min_parallax_deg);
  ORBATLAS_CHECK(min_triangulated >= 1, "two-view reconstruction: min_triangulated must be >= 1");
  ORBATLAS_CHECK(min_good_fraction > 0.0 && min_good_fraction <= 1.0,
                 "two-view reconstruction: min_good_fraction must be in (0, 1]");
  ORBATLAS_CHECK(max_second_ratio > 0.0 && max_second_ratio < 1.0 && max_second_ratio_homography > 0.0 &&
                     max_second_ratio_homography < 1.0,
                 "two-view reconstruction: max_second_ratio(_homography) must be in (0, 1)");
}

const char* to_string(TwoViewModel model) {
  switch (model) {
    case TwoViewModel::kHomography:
      return "homography";
    case TwoViewModel::kFundamental:
      return "fundamental";
    case TwoViewModel::kNone:
      break;
  }
  return "none";
}

namespace {

// The chi2 95 % quantiles (1 and 2 degrees of freedom) ORB-SLAM scores with.
constexpr double kChi2OneDof = 3.841;
constexpr double kChi2TwoDof = 5.991;
constexpr double kMaxCosParallax = 0.99998;  // rays closer than this are not triangulated reliably

// Hartley's normalisation: centroid to the origin, mean absolute deviation 1 per axis.
Eigen::Matrix3d normalisation(const std::vector<Eigen::Vector2d>& x) {
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& p : x) mean += p;
  mean /= static_cast<double>(x.size());
  Eigen::Vector2d dev = Eigen::Vector2d::Zero();
  for (const auto& p : x) dev += (p - mean).cwiseAbs();
  dev /= static_cast<double>(x.size());
  if (dev.x() <= 0.0 || dev.y() <= 0.0) return Eigen::Matrix3d::Zero();
  Eigen::Matrix3d T = Eigen::Matrix3d::Identity();
  T(0, 0) = 1.0 / dev.x();
  T(1, 1) = 1.0 / dev.y();
  T(0, 2) = -mean.x() / dev.x();
  T(1, 2) = -mean.y() / dev.y();
  return T;
}

Eigen::Vector2d apply(const Eigen::Matrix3d& T, const Eigen::Vector2d& p) {
  return (T * p.homogeneous()).hnormalized();
}

// Symmetric transfer score of a homography (ORB-SLAM's CheckHomography): each
// match inside both chi2 bounds adds what it leaves of them.
double score_homography(const Eigen::Matrix3d& H21, const std::vector<Eigen::Vector2d>& x1,
                        const std::vector<Eigen::Vector2d>& x2, double inv_sigma2, std::vector<std::uint8_t>* inliers) {
  const Eigen::Matrix3d H12 = H21.inverse();
  double score = 0.0;
  inliers->assign(x1.size(), 0);
  for (std::size_t i = 0; i < x1.size(); ++i) {
    const Eigen::Vector3d in2 = H21 * x1[i].homogeneous(), in1 = H12 * x2[i].homogeneous();
    if (std::abs(in2.z()) < 1e-12 || std::abs(in1.z()) < 1e-12) continue;
    const double chi2_2 = (in2.hnormalized() - x2[i]).squaredNorm() * inv_sigma2;
    const double chi2_1 = (in1.hnormalized() - x1[i]).squaredNorm() * inv_sigma2;
    if (!(chi2_1 <= kChi2TwoDof) || !(chi2_2 <= kChi2TwoDof)) continue;
    score += (kChi2TwoDof - chi2_1) + (kChi2TwoDof - chi2_2);
    (*inliers)[i] = 1;
  }
  return score;
}

// Symmetric epipolar score of a fundamental matrix (ORB-SLAM's
// CheckFundamental): distances to the epipolar lines, bounded at the 1-dof
// quantile, scored against the 2-dof one (comparable with the homography's).
double score_fundamental(const Eigen::Matrix3d& F21, const std::vector<Eigen::Vector2d>& x1,
                         const std::vector<Eigen::Vector2d>& x2, double inv_sigma2,
                         std::vector<std::uint8_t>* inliers) {
  double score = 0.0;
  inliers->assign(x1.size(), 0);
  for (std::size_t i = 0; i < x1.size(); ++i) {
    const Eigen::Vector3d p1 = x1[i].homogeneous(), p2 = x2[i].homogeneous();
    const Eigen::Vector3d l2 = F21 * p1, l1 = F21.transpose() * p2;
    const double n2 = l2.head<2>().squaredNorm(), n1 = l1.head<2>().squaredNorm();
    if (n1 <= 0.0 || n2 <= 0.0) continue;
    const double chi2_2 = std::pow(l2.dot(p2), 2) / n2 * inv_sigma2;
    const double chi2_1 = std::pow(l1.dot(p1), 2) / n1 * inv_sigma2;
    if (!(chi2_1 <= kChi2OneDof) || !(chi2_2 <= kChi2OneDof)) continue;
    score += (kChi2TwoDof - chi2_1) + (kChi2TwoDof - chi2_2);
    (*inliers)[i] = 1;
  }
  return score;
}

struct PoseCheck {
  Eigen::Matrix3d R;
  Eigen::Vector3d t;
  int good = 0;
  double parallax_deg = 0.0;
  std::vector<std::uint8_t> triangulated;
  std::vector<Eigen::Vector3d> points_c1;
};

// Triangulates the inliers with camera 2 at (R, t) from camera 1 (ORB-SLAM's
// CheckRT): good points are finite, in front of both cameras, within th2 of
// their observations in both views; they
// count as triangulated when their rays are not nearly parallel. The parallax
// is that of the 51st widest ray pair (fewer points: the narrowest).
PoseCheck check_pose(const Eigen::Matrix3d& R, const Eigen::Vector3d& t, const std::vector<Eigen::Vector2d>& x1,
                     const std::vector<Eigen::Vector2d>& x2, const std::vector<std::uint8_t>& inliers, double th2) {
  PoseCheck c;
  c.R = R;
  c.t = t;
  c.triangulated.assign(x1.size(), 0);
  c.points_c1.assign(x1.size(), Eigen::Vector3d::Zero());
  const Pose3 T_c1_c1;
  const Pose3 T_c2_c1(Eigen::Quaterniond(R), t);
  const Eigen::Vector3d o2 = -R.transpose() * t;  // camera 2's centre in camera 1
  std::vector<double> cos_parallax;
  for (std::size_t i = 0; i < x1.size(); ++i) {
    if (!inliers[i]) continue;
    Eigen::Vector3d p;
    if (!triangulate_dlt(x1[i], x2[i], T_c1_c1, T_c2_c1, &p)) continue;
    const Eigen::Vector3d ray1 = p, ray2 = p - o2;
    const double cos_par = ray1.dot(ray2) / (ray1.norm() * ray2.norm());
    const Eigen::Vector3d p2 = R * p + t;
    if (p.z() <= 0.0 || p2.z() <= 0.0) continue;  // behind a camera
    if ((p.head<2>() / p.z() - x1[i]).squaredNorm() > th2) continue;
    if ((p2.head<2>() / p2.z() - x2[i]).squaredNorm() > th2) continue;
    ++c.good;
    cos_parallax.push_back(cos_par);
    c.points_c1[i] = p;
    if (cos_par < kMaxCosParallax) c.triangulated[i] = 1;
  }
  if (!cos_parallax.empty()) {
    std::sort(cos_parallax.begin(), cos_parallax.end());  // widest first
    const std::size_t k = std::min<std::size_t>(50, cos_parallax.size() - 1);
    c.parallax_deg = std::acos(std::clamp(cos_parallax[k], -1.0, 1.0)) * 180.0 / M_PI;
  }
  return c;
}

// Chooses among the candidate poses: the one with most good points, when no
// other comes close, it triangulates enough of the model's inliers and sees
// them with enough parallax.
bool choose_pose(std::vector<PoseCheck>& checks, int inliers, double second_ratio, const TwoViewOptions& options,
                 TwoViewResult* result) {
  std::sort(checks.begin(), checks.end(), [](const PoseCheck& a, const PoseCheck& b) { return a.good > b.good; });
  const PoseCheck& best = checks.front();
  const int second = checks.size() > 1 ? checks[1].good : 0;
  const int needed = std::max(static_cast<int>(options.min_good_fraction * inliers), options.min_triangulated);
  if (best.good < needed) {
    result->failure = "the best pose triangulates " + std::to_string(best.good) + " of " + std::to_string(inliers) +
                      " inliers (" + std::to_string(needed) + " needed)";
    return false;
  }
  if (second > second_ratio * best.good) {
    result->failure =
        "ambiguous: two poses triangulate " + std::to_string(best.good) + " and " + std::to_string(second) + " points";
    return false;
  }
  if (best.parallax_deg < options.min_parallax_deg) {
    result->failure = "too little parallax (" + std::to_string(best.parallax_deg) + " deg)";
    return false;
  }
  result->T_c2_c1 = Pose3(Eigen::Quaterniond(best.R), best.t);
  result->triangulated = best.triangulated;
  result->points_c1 = best.points_c1;
  result->triangulated_count =
      static_cast<int>(std::count(best.triangulated.begin(), best.triangulated.end(), std::uint8_t{1}));
  result->parallax_deg = best.parallax_deg;
  return true;
}

// The essential matrix's four (R, t) (ORB-SLAM's ReconstructF on the normalised plane).
std::vector<std::pair<Eigen::Matrix3d, Eigen::Vector3d>> essential_poses(const Eigen::Matrix3d& E) {
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(E, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Matrix3d U = svd.matrixU(), V = svd.matrixV();
  Eigen::Matrix3d W;
  W << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  Eigen::Matrix3d R1 = U * W * V.transpose(), R2 = U * W.transpose() * V.transpose();
  if (R1.determinant() < 0) R1 = -R1;
  if (R2.determinant() < 0) R2 = -R2;
  const Eigen::Vector3d t = U.col(2).normalized();
  return {{R1, t}, {R1, -t}, {R2, t}, {R2, -t}};
}

// The homography's eight (R, t) (Faugeras and Lustman's decomposition, as
// ORB-SLAM's ReconstructH); empty when two singular values coincide.
std::vector<std::pair<Eigen::Matrix3d, Eigen::Vector3d>> homography_poses(const Eigen::Matrix3d& H) {
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Matrix3d U = svd.matrixU(), V = svd.matrixV();
  const double s = U.determinant() * V.determinant();
  const double d1 = svd.singularValues()(0), d2 = svd.singularValues()(1), d3 = svd.singularValues()(2);
  std::vector<std::pair<Eigen::Matrix3d, Eigen::Vector3d>> poses;
  if (d1 / d2 < 1.00001 || d2 / d3 < 1.00001) return poses;
  const double a1 = std::sqrt((d1 * d1 - d2 * d2) / (d1 * d1 - d3 * d3));
  const double a3 = std::sqrt((d2 * d2 - d3 * d3) / (d1 * d1 - d3 * d3));
  const double x1[4] = {a1, a1, -a1, -a1}, x3[4] = {a3, -a3, a3, -a3};
  // d' = d2
  const double s_theta = std::sqrt((d1 * d1 - d2 * d2) * (d2 * d2 - d3 * d3)) / ((d1 + d3) * d2);
  const double c_theta = (d2 * d2 + d1 * d3) / ((d1 + d3) * d2);
  const double stheta[4] = {s_theta, -s_theta, -s_theta, s_theta};
  for (int i = 0; i < 4; ++i) {
    Eigen::Matrix3d Rp;
    Rp << c_theta, 0, -stheta[i], 0, 1, 0, stheta[i], 0, c_theta;
    const Eigen::Vector3d tp = Eigen::Vector3d(x1[i], 0, -x3[i]) * (d1 - d3);
    poses.emplace_back(s * U * Rp * V.transpose(), (U * tp).normalized());
  }
  // d' = -d2
  const double s_phi = std::sqrt((d1 * d1 - d2 * d2) * (d2 * d2 - d3 * d3)) / ((d1 - d3) * d2);
  const double c_phi = (d1 * d3 - d2 * d2) / ((d1 - d3) * d2);
  const double sphi[4] = {s_phi, -s_phi, -s_phi, s_phi};
  for (int i = 0; i < 4; ++i) {
    Eigen::Matrix3d Rp;
    Rp << c_phi, 0, sphi[i], 0, -1, 0, sphi[i], 0, -c_phi;
    const Eigen::Vector3d tp = Eigen::Vector3d(x1[i], 0, x3[i]) * (d1 + d3);
    poses.emplace_back(s * U * Rp * V.transpose(), (U * tp).normalized());
  }
  return poses;
}

}  // namespace

Eigen::Matrix3d homography_dlt(const std::vector<Eigen::Vector2d>& x1, const std::vector<Eigen::Vector2d>& x2) {
  ORBATLAS_CHECK(x1.size() == x2.size() && x1.size() >= 4, "homography: needs >= 4 matches");
  const Eigen::Matrix3d T1 = normalisation(x1), T2 = normalisation(x2);
  if (T1.isZero() || T2.isZero()) return Eigen::Matrix3d::Zero();
  Eigen::MatrixXd A(2 * x1.size(), 9);
  for (std::size_t i = 0; i < x1.size(); ++i) {
    const Eigen::Vector2d p = apply(T1, x1[i]), q = apply(T2, x2[i]);
    A.row(2 * i) << 0, 0, 0, -p.x(), -p.y(), -1, q.y() * p.x(), q.y() * p.y(), q.y();
    A.row(2 * i + 1) << p.x(), p.y(), 1, 0, 0, 0, -q.x() * p.x(), -q.x() * p.y(), -q.x();
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(A, Eigen::ComputeFullV);
  const Eigen::VectorXd h = svd.matrixV().col(8);
  Eigen::Matrix3d Hn;
  Hn << h(0), h(1), h(2), h(3), h(4), h(5), h(6), h(7), h(8);
  const Eigen::Matrix3d H = T2.inverse() * Hn * T1;
  return H.allFinite() ? H : Eigen::Matrix3d::Zero();
}

Eigen::Matrix3d fundamental_eight_point(const std::vector<Eigen::Vector2d>& x1,
                                        const std::vector<Eigen::Vector2d>& x2) {
  ORBATLAS_CHECK(x1.size() == x2.size() && x1.size() >= 8, "fundamental matrix: needs >= 8 matches");
  const Eigen::Matrix3d T1 = normalisation(x1), T2 = normalisation(x2);
  if (T1.isZero() || T2.isZero()) return Eigen::Matrix3d::Zero();
  Eigen::MatrixXd A(x1.size(), 9);
  for (std::size_t i = 0; i < x1.size(); ++i) {
    const Eigen::Vector2d p = apply(T1, x1[i]), q = apply(T2, x2[i]);
    A.row(i) << q.x() * p.x(), q.x() * p.y(), q.x(), q.y() * p.x(), q.y() * p.y(), q.y(), p.x(), p.y(), 1;
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(A, Eigen::ComputeFullV);
  const Eigen::VectorXd f = svd.matrixV().col(8);
  Eigen::Matrix3d Fn;
  Fn << f(0), f(1), f(2), f(3), f(4), f(5), f(6), f(7), f(8);
  Eigen::JacobiSVD<Eigen::Matrix3d> rank(Fn, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Vector3d sv = rank.singularValues();
  sv(2) = 0.0;
  Fn = rank.matrixU() * sv.asDiagonal() * rank.matrixV().transpose();
  const Eigen::Matrix3d F = T2.transpose() * Fn * T1;
  return F.allFinite() ? F : Eigen::Matrix3d::Zero();
}

TwoViewResult reconstruct_two_views(const std::vector<Eigen::Vector2d>& x1, const std::vector<Eigen::Vector2d>& x2,
                                    const TwoViewOptions& options) {
  options.check();
  ORBATLAS_CHECK(x1.size() == x2.size(),
                 "two-view reconstruction: " << x1.size() << " against " << x2.size() << " points");
  TwoViewResult result;
  const std::size_t n = x1.size();
  if (n < 8) {
    result.failure = "too few matches (" + std::to_string(n) + ", 8 needed)";
    return result;
  }
  const double sigma = options.sigma_px / options.focal_px;
  const double inv_sigma2 = 1.0 / (sigma * sigma);

  // RANSAC: the same minimal sets for both models.
  std::mt19937_64 rng(options.seed);
  std::vector<std::size_t> all(n);
  std::iota(all.begin(), all.end(), 0);
  std::vector<Eigen::Vector2d> s1(8), s2(8);
  std::vector<std::uint8_t> inliers, best_h_inliers, best_f_inliers;
  for (int it = 0; it < options.iterations; ++it) {
    for (std::size_t k = 0; k < 8; ++k) {  // a partial Fisher-Yates shuffle: 8 distinct matches
      std::uniform_int_distribution<std::size_t> pick(k, n - 1);
      std::swap(all[k], all[pick(rng)]);
      s1[k] = x1[all[k]];
      s2[k] = x2[all[k]];
    }
    const Eigen::Matrix3d H = homography_dlt(s1, s2);
    if (!H.isZero() && std::abs(H.determinant()) > 1e-12) {
      const double score = score_homography(H, x1, x2, inv_sigma2, &inliers);
      if (score > result.score_homography) {
        result.score_homography = score;
        result.H_21 = H;
        best_h_inliers = inliers;
      }
    }
    const Eigen::Matrix3d F = fundamental_eight_point(s1, s2);
    if (!F.isZero()) {
      const double score = score_fundamental(F, x1, x2, inv_sigma2, &inliers);
      if (score > result.score_fundamental) {
        result.score_fundamental = score;
        result.F_21 = F;
        best_f_inliers = inliers;
      }
    }
  }
  // Both models fitted again on all their inliers (linear, but far better
  // conditioned than eight matches), kept when they score no lower.
  const auto inlier_matches = [&](const std::vector<std::uint8_t>& in, std::vector<Eigen::Vector2d>* a,
                                  std::vector<Eigen::Vector2d>* b) {
    a->clear();
    b->clear();
    for (std::size_t i = 0; i < in.size(); ++i)
      if (in[i]) {
        a->push_back(x1[i]);
        b->push_back(x2[i]);
      }
  };
  std::vector<Eigen::Vector2d> a, b;
  inlier_matches(best_h_inliers, &a, &b);
  if (a.size() >= 8) {
    const Eigen::Matrix3d H = homography_dlt(a, b);
    if (!H.isZero() && std::abs(H.determinant()) > 1e-12) {
      const double score = score_homography(H, x1, x2, inv_sigma2, &inliers);
      if (score >= result.score_homography) {
        result.score_homography = score;
        result.H_21 = H;
        best_h_inliers = inliers;
      }
    }
  }
  inlier_matches(best_f_inliers, &a, &b);
  if (a.size() >= 8) {
    const Eigen::Matrix3d F = fundamental_eight_point(a, b);
    if (!F.isZero()) {
      const double score = score_fundamental(F, x1, x2, inv_sigma2, &inliers);
      if (score >= result.score_fundamental) {
        result.score_fundamental = score;
        result.F_21 = F;
        best_f_inliers = inliers;
      }
    }
  }

  const double total = result.score_homography + result.score_fundamental;
  if (total <= 0.0) {
    result.failure = "neither a homography nor a fundamental matrix explains the matches";
    return result;
  }
  result.homography_ratio = result.score_homography / total;
  const double th2 = 4.0 * sigma * sigma;  // ORB-SLAM: 4 sigma^2 (2 px at sigma 1 px)
  std::vector<PoseCheck> checks;
  if (result.homography_ratio > options.homography_ratio) {
    result.model = TwoViewModel::kHomography;
    for (const auto& [R, t] : homography_poses(result.H_21))
      checks.push_back(check_pose(R, t, x1, x2, best_h_inliers, th2));
    if (checks.empty()) {
      result.failure = "the homography does not decompose (two singular values coincide)";
      return result;
    }
    const int count = static_cast<int>(std::count(best_h_inliers.begin(), best_h_inliers.end(), std::uint8_t{1}));
    result.success = choose_pose(checks, count, options.max_second_ratio_homography, options, &result);
  } else {
    result.model = TwoViewModel::kFundamental;
    for (const auto& [R, t] : essential_poses(result.F_21))
      checks.push_back(check_pose(R, t, x1, x2, best_f_inliers, th2));
    const int count = static_cast<int>(std::count(best_f_inliers.begin(), best_f_inliers.end(), std::uint8_t{1}));
    result.success = choose_pose(checks, count, options.max_second_ratio, options, &result);
  }
  return result;
}

}  // namespace orbatlas
