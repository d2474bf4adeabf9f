#include "core/sim/trajectory_spline.h"

#include <cmath>

#include "core/common/error.h"
#include "core/geometry/so3.h"

namespace orbatlas::sim {
namespace {

// Cumulative basis of the uniform cubic B-spline and its derivatives in u.
struct CumulativeBasis {
  double b[4], db[4], ddb[4];
};

CumulativeBasis cumulative_basis(double u) {
  const double u2 = u * u, u3 = u2 * u;
  CumulativeBasis c{};
  c.b[0] = 1.0;
  c.b[1] = (5.0 + 3.0 * u - 3.0 * u2 + u3) / 6.0;
  c.b[2] = (1.0 + 3.0 * u + 3.0 * u2 - 2.0 * u3) / 6.0;
  c.b[3] = u3 / 6.0;
  c.db[0] = 0.0;
  c.db[1] = (3.0 - 6.0 * u + 3.0 * u2) / 6.0;
  c.db[2] = (3.0 + 6.0 * u - 6.0 * u2) / 6.0;
  c.db[3] = 3.0 * u2 / 6.0;
  c.ddb[0] = 0.0;
  c.ddb[1] = (-6.0 + 6.0 * u) / 6.0;
  c.ddb[2] = (6.0 - 12.0 * u) / 6.0;
  c.ddb[3] = 6.0 * u / 6.0;
  return c;
}

// Gaussian-smoothed pose of the samples at time t (positions averaged; rotations
// averaged in the tangent space of the nearest sample).
Pose3 smoothed_sample(const Trajectory& s, TimestampNs t, double sigma_s) {
  const auto it =
      std::lower_bound(s.begin(), s.end(), t, [](const StampedPose& a, TimestampNs v) { return a.t_ns < v; });
  std::size_t centre =
      static_cast<std::size_t>(std::min<std::ptrdiff_t>(it - s.begin(), static_cast<std::ptrdiff_t>(s.size()) - 1));
  if (centre > 0 && std::llabs(s[centre - 1].t_ns - t) < std::llabs(s[centre].t_ns - t)) --centre;
  const auto exact = pose_at(s, t, kNsPerSecond / 5);
  const Pose3 ref = exact ? *exact : s[centre].pose;
  if (sigma_s <= 0.0) return ref;
  const TimestampNs window = s_to_ns(3.0 * sigma_s);
  Eigen::Vector3d p_sum = Eigen::Vector3d::Zero(), w_sum = Eigen::Vector3d::Zero();
  double total = 0.0;
  for (std::size_t k = centre; k-- > 0 && t - s[k].t_ns <= window;) {
    const double w = std::exp(-0.5 * std::pow(ns_to_s(t - s[k].t_ns) / sigma_s, 2));
    p_sum += w * s[k].pose.t;
    w_sum += w * so3_log(ref.q.conjugate() * s[k].pose.q);
    total += w;
  }
  for (std::size_t k = centre; k < s.size() && s[k].t_ns - t <= window; ++k) {
    const double w = std::exp(-0.5 * std::pow(ns_to_s(s[k].t_ns - t) / sigma_s, 2));
    p_sum += w * s[k].pose.t;
    w_sum += w * so3_log(ref.q.conjugate() * s[k].pose.q);
    total += w;
  }
  return Pose3(ref.q * so3_exp(w_sum / total), p_sum / total);
}

}  // namespace

void SplineOptions::check() const {
  ORBATLAS_CHECK(std::isfinite(knot_spacing_s) && knot_spacing_s >= 1e-9,
                 "trajectory spline: knot_spacing_s must be a finite value >= 1e-9 (1 ns), not " << knot_spacing_s);
  ORBATLAS_CHECK(std::isfinite(smoothing_sigma_s),
                 "trajectory spline: smoothing_sigma_s must be finite (<= 0: no smoothing), not " << smoothing_sigma_s);
}

TrajectorySpline::TrajectorySpline(const Trajectory& samples, const SplineOptions& options) {
  options.check();
  ORBATLAS_CHECK(samples.size() >= 8, "trajectory spline needs at least 8 samples, got " << samples.size());
  check_strictly_increasing(samples, "trajectory spline samples");
  spacing_ns_ = s_to_ns(options.knot_spacing_s);
  const TimestampNs t0 = samples.front().t_ns, t1 = samples.back().t_ns;
  const auto n = static_cast<std::size_t>((t1 - t0) / spacing_ns_) + 1;
  ORBATLAS_CHECK(n >= 4, "trajectory too short for the spline: " << ns_to_s(t1 - t0) << " s");
  positions_.reserve(n);
  rotations_.reserve(n);
  for (std::size_t k = 0; k < n; ++k) {
    const TimestampNs t = t0 + static_cast<TimestampNs>(k) * spacing_ns_;
    const auto raw = pose_at(samples, t, kNsPerSecond / 10);
    ORBATLAS_CHECK(raw.has_value(), "ground truth has a gap of more than 0.1 s around " << format_seconds_exact(t));
    const Pose3 p = smoothed_sample(samples, t, options.smoothing_sigma_s);
    Eigen::Quaterniond q = p.q;
    if (!rotations_.empty() && rotations_.back().dot(q) < 0.0) q.coeffs() = -q.coeffs();
    positions_.push_back(p.t);
    rotations_.push_back(q);
  }
  rotation_deltas_.assign(n, Eigen::Vector3d::Zero());
  for (std::size_t k = 1; k < n; ++k) rotation_deltas_[k] = so3_log(rotations_[k - 1].conjugate() * rotations_[k]);
  // Control point k sits at t0 + k * spacing; segment i (u in [0,1)) uses points
  // i..i+3 and spans [t0 + (i+1) spacing, t0 + (i+2) spacing).
  first_knot_ns_ = t0 + spacing_ns_;
  start_ns_ = first_knot_ns_;
  end_ns_ = t0 + static_cast<TimestampNs>(n - 2) * spacing_ns_;
}

SplineState TrajectorySpline::evaluate(TimestampNs t) const {
  ORBATLAS_CHECK(covers(t), "time " << format_seconds_exact(t) << " outside the trajectory ["
                                    << format_seconds_exact(start_ns_) << ", " << format_seconds_exact(end_ns_) << "]");
  const TimestampNs rel = t - first_knot_ns_;
  auto i = static_cast<std::size_t>(rel / spacing_ns_);
  if (i + 3 >= positions_.size()) i = positions_.size() - 4;  // t == end
  const double u =
      static_cast<double>(rel - static_cast<TimestampNs>(i) * spacing_ns_) / static_cast<double>(spacing_ns_);
  const double inv_dt = 1e9 / static_cast<double>(spacing_ns_);
  const CumulativeBasis c = cumulative_basis(u);

  SplineState s;
  Eigen::Vector3d p = positions_[i], v = Eigen::Vector3d::Zero(), a = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q = rotations_[i];
  Eigen::Vector3d omega = Eigen::Vector3d::Zero();
  for (int j = 1; j <= 3; ++j) {
    const Eigen::Vector3d dp = positions_[i + j] - positions_[i + j - 1];
    p += c.b[j] * dp;
    v += c.db[j] * inv_dt * dp;
    a += c.ddb[j] * inv_dt * inv_dt * dp;
    const Eigen::Vector3d& d = rotation_deltas_[i + j];
    const Eigen::Quaterniond step = so3_exp(c.b[j] * d);
    q = q * step;
    // Body rate of a product R = R_i A_1 A_2 A_3: carry the previous rate into
    // the new factor's frame and add this factor's own rate.
    omega = step.conjugate() * omega + c.db[j] * inv_dt * d;
  }
  s.T_w_b = Pose3(q, p);
  s.v_w = v;
  s.a_w = a;
  s.omega_b = omega;
  return s;
}

}  // namespace orbatlas::sim
