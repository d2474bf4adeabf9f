#include "core/imu/time_offset_estimate.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/common/error.h"
#include "core/geometry/so3.h"
#include "core/imu/preintegration.h"

namespace orbatlas {
namespace {

// The gyro integrated from IMU time t0 to t1 (the samples' intervals held at
// the mean of their ends, as Preintegration does) at bias `bg`, and the
// rotation's first-order Jacobian in the bias; none when the samples do not
// cover [t0, t1] or leave a gap over 50 ms in it.
struct Turn {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d dR_dbg = Eigen::Matrix3d::Zero();
};

std::optional<Turn> integrate_gyro(const std::vector<ImuSample>& samples, TimestampNs t0, TimestampNs t1,
                                   const Eigen::Vector3d& bg) {
  if (samples.size() < 2 || samples.front().t_ns > t0 || samples.back().t_ns < t1) return std::nullopt;
  auto it = std::upper_bound(samples.begin(), samples.end(), t0,
                             [](TimestampNs t, const ImuSample& s) { return t < s.t_ns; });
  std::size_t k = static_cast<std::size_t>(std::distance(samples.begin(), it)) - 1;
  Turn turn;
  for (; k + 1 < samples.size() && samples[k].t_ns < t1; ++k) {
    const ImuSample& a = samples[k];
    const ImuSample& b = samples[k + 1];
    if (b.t_ns - a.t_ns > 50'000'000) return std::nullopt;
    const TimestampNs from = std::max(t0, a.t_ns), to = std::min(t1, b.t_ns);
    if (to <= from) continue;
    const double span = static_cast<double>(b.t_ns - a.t_ns);
    const double s0 = static_cast<double>(from - a.t_ns) / span, s1 = static_cast<double>(to - a.t_ns) / span;
    const Eigen::Vector3d w = a.gyro + 0.5 * (s0 + s1) * (b.gyro - a.gyro) - bg;
    const double dt = static_cast<double>(to - from) * 1e-9;
    const Eigen::Matrix3d dR = so3_exp(w * dt).toRotationMatrix();
    turn.dR_dbg = dR.transpose() * turn.dR_dbg - so3_right_jacobian(w * dt) * dt;
    turn.R = turn.R * dR;
  }
  return turn;
}

struct Pair {
  TimestampNs t0 = 0, t1 = 0;
  Eigen::Matrix3d R_vis;  // the IMU's turn from the first frame to the second, by the images
};

// Each pair's rotation residual (images against the gyro at bias `bg`, no
// offset, the bias solved for); false when the IMU does not cover a pair.
bool pair_residuals(const std::vector<Pair>& pairs, const std::vector<ImuSample>& samples, const Eigen::Vector3d& bg,
                    std::vector<Eigen::Vector3d>* out) {
  out->clear();
  for (const auto& p : pairs) {
    const auto turn = integrate_gyro(samples, p.t0, p.t1, bg);
    if (!turn) return false;
    out->push_back(so3_log(Eigen::Quaterniond(turn->R.transpose() * p.R_vis)));
  }
  return true;
}

// Sum of the pairs' squared rotation residuals at offset `d` with the gyro
// bias solved for (linearised at `bg0`); each pair's capped at (5 mrad)^2 so
// that a pair across a jump of the map weighs little. Infinity when the IMU
// does not cover a pair.
double cost_at(const std::vector<Pair>& pairs, const std::vector<ImuSample>& samples, double d,
               const Eigen::Vector3d& bg0, Eigen::Vector3d* bg_out) {
  const TimestampNs shift = s_to_ns(d);
  std::vector<Eigen::Vector3d> r0(pairs.size());
  std::vector<Eigen::Matrix3d> J(pairs.size());
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  Eigen::Vector3d g = Eigen::Vector3d::Zero();
  for (std::size_t k = 0; k < pairs.size(); ++k) {
    const auto turn = integrate_gyro(samples, pairs[k].t0 + shift, pairs[k].t1 + shift, bg0);
    if (!turn) return std::numeric_limits<double>::infinity();
    // Residual of the turns, and its change with the bias: R(bg) ~ R(bg0) Exp(dR_dbg (bg - bg0)),
    // so the residual at bg is about r0 - dR_dbg (bg - bg0).
    r0[k] = so3_log(Eigen::Quaterniond(turn->R.transpose() * pairs[k].R_vis));
    J[k] = turn->dR_dbg;
    H += J[k].transpose() * J[k];
    g += J[k].transpose() * r0[k];
  }
  const Eigen::Vector3d delta = H.ldlt().solve(g);
  if (bg_out) *bg_out = bg0 + delta;
  constexpr double kCap = 5e-3 * 5e-3;
  double cost = 0.0;
  for (std::size_t k = 0; k < pairs.size(); ++k) cost += std::min((r0[k] - J[k] * delta).squaredNorm(), kCap);
  return cost;
}

}  // namespace

void ImuTimeOffsetOptions::check() const {
  ORBATLAS_CHECK(std::isfinite(max_offset_s) && max_offset_s > 0.0 && max_offset_s <= 0.5,
                 "imu time offset: max_offset_s must be in (0, 0.5], not " << max_offset_s);
  ORBATLAS_CHECK(std::isfinite(window_s) && window_s > 0.0, "imu time offset: window_s must be > 0, not " << window_s);
  ORBATLAS_CHECK(std::isfinite(every_s) && every_s > 0.0, "imu time offset: every_s must be > 0, not " << every_s);
  ORBATLAS_CHECK(std::isfinite(pair_s) && pair_s > 0.0 && pair_s < window_s,
                 "imu time offset: pair_s must be in (0, window_s), not " << pair_s);
  ORBATLAS_CHECK(std::isfinite(min_rate_change) && min_rate_change >= 0.0,
                 "imu time offset: min_rate_change must be >= 0, not " << min_rate_change);
  ORBATLAS_CHECK(std::isfinite(max_pair_residual) && max_pair_residual > 0.0,
                 "imu time offset: max_pair_residual must be > 0, not " << max_pair_residual);
  ORBATLAS_CHECK(min_windows >= 1, "imu time offset: min_windows must be >= 1");
  ORBATLAS_CHECK(max_windows >= min_windows, "imu time offset: max_windows must be >= min_windows");
}

ImuTimeOffset::ImuTimeOffset(ImuTimeOffsetOptions options) : options_(options) { options_.check(); }

void ImuTimeOffset::add_frame(TimestampNs t_ns, const Eigen::Quaterniond& q_w_i) {
  if (!options_.enabled) return;
  if (!frames_.empty() && t_ns <= frames_.back().t_ns) return;
  frames_.push_back({t_ns, q_w_i.normalized()});
  while (!frames_.empty() && ns_to_s(t_ns - frames_.front().t_ns) > options_.window_s) frames_.pop_front();
}

void ImuTimeOffset::reset() { frames_.clear(); }

bool ImuTimeOffset::update(const std::vector<ImuSample>& samples) {
  if (!options_.enabled || frames_.size() < 2) return false;
  const TimestampNs newest = frames_.back().t_ns;
  if (ns_to_s(newest - frames_.front().t_ns) < 0.9 * options_.window_s) return false;
  if (last_fit_ns_ != 0 && ns_to_s(newest - last_fit_ns_) < options_.every_s) return false;
  last_fit_ns_ = newest;
  const std::vector<Frame> window(frames_.begin(), frames_.end());
  const auto found = fit(window, samples, options_);
  if (!found) return false;
  estimates_.push_back(found->offset_s);
  while (estimates_.size() > options_.max_windows) estimates_.pop_front();
  return estimates_.size() >= options_.min_windows;
}

std::optional<double> ImuTimeOffset::offset_s() const {
  if (estimates_.size() < options_.min_windows) return std::nullopt;
  std::vector<double> sorted(estimates_.begin(), estimates_.end());
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2), sorted.end());
  return sorted[sorted.size() / 2];
}

std::optional<ImuTimeOffset::Fit> ImuTimeOffset::fit(const std::vector<Frame>& frames,
                                                     const std::vector<ImuSample>& samples,
                                                     const ImuTimeOffsetOptions& options) {
  // Pairs of frames pair_s apart, one starting every half pair_s.
  std::vector<Pair> pairs;
  double rate_change_sq = 0.0;
  const auto rate_at = [&](std::size_t i) {  // the images' angular rate at frame i (to the next frame)
    const std::size_t j = std::min(i + 1, frames.size() - 1), h = j == i ? i - 1 : i;
    const double dt = ns_to_s(frames[j].t_ns - frames[h].t_ns);
    return Eigen::Vector3d(so3_log(frames[h].q_w_i.conjugate() * frames[j].q_w_i) / dt);
  };
  TimestampNs next_start = 0;
  for (std::size_t i = 0, j = 0; i + 1 < frames.size(); ++i) {
    if (frames[i].t_ns < next_start) continue;
    j = std::max(j, i + 1);
    while (j < frames.size() && ns_to_s(frames[j].t_ns - frames[i].t_ns) < options.pair_s) ++j;
    if (j >= frames.size()) break;
    if (ns_to_s(frames[j].t_ns - frames[i].t_ns) > 1.5 * options.pair_s) continue;  // a gap in the frames
    pairs.push_back({frames[i].t_ns, frames[j].t_ns,
                     (frames[i].q_w_i.conjugate() * frames[j].q_w_i).normalized().toRotationMatrix()});
    rate_change_sq += (rate_at(j) - rate_at(i)).squaredNorm();
    next_start = frames[i].t_ns + s_to_ns(options.pair_s / 2.0);
  }
  if (pairs.size() < 8) return std::nullopt;
  if (std::sqrt(rate_change_sq / static_cast<double>(pairs.size())) < options.min_rate_change) return std::nullopt;

  // Pairs across a jump of the map (its gravity alignment turns it, a loop
  // correction moves it) disagree with the gyro by far more than any offset
  // within max_offset_s explains: left out, they would skew the bias.
  std::vector<Eigen::Vector3d> residuals;
  if (!pair_residuals(pairs, samples, Eigen::Vector3d::Zero(), &residuals)) return std::nullopt;
  Eigen::Vector3d typical;  // the bias's part, about the same in every pair: the median per axis
  for (int a = 0; a < 3; ++a) {
    std::vector<double> v;
    for (const auto& r : residuals) v.push_back(r[a]);
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    typical[a] = v[v.size() / 2];
  }
  std::vector<Pair> kept;
  for (std::size_t k = 0; k < pairs.size(); ++k)
    if ((residuals[k] - typical).norm() < options.max_pair_residual) kept.push_back(pairs[k]);
  if (kept.size() < 8 || kept.size() * 4 < pairs.size() * 3) return std::nullopt;
  pairs.swap(kept);

  // A coarse scan, then a golden-section search about its best.
  Eigen::Vector3d bg = Eigen::Vector3d::Zero();
  cost_at(pairs, samples, 0.0, Eigen::Vector3d::Zero(), &bg);  // the bias, near enough to linearise at
  const double step = 0.0025;
  double best = 0.0, best_cost = std::numeric_limits<double>::infinity();
  for (double d = -options.max_offset_s; d <= options.max_offset_s + 1e-12; d += step) {
    const double c = cost_at(pairs, samples, d, bg, nullptr);
    if (c < best_cost) {
      best_cost = c;
      best = d;
    }
  }
  if (!std::isfinite(best_cost)) return std::nullopt;
  if (std::abs(best) > options.max_offset_s - step / 2.0) return std::nullopt;  // at the edge: not bracketed
  constexpr double kPhi = 0.6180339887498949;
  double a = best - step, b = best + step;
  double x1 = b - kPhi * (b - a), x2 = a + kPhi * (b - a);
  double f1 = cost_at(pairs, samples, x1, bg, nullptr), f2 = cost_at(pairs, samples, x2, bg, nullptr);
  while (b - a > 5e-5) {
    if (f1 < f2) {
      b = x2;
      x2 = x1;
      f2 = f1;
      x1 = b - kPhi * (b - a);
      f1 = cost_at(pairs, samples, x1, bg, nullptr);
    } else {
      a = x1;
      x1 = x2;
      f1 = f2;
      x2 = a + kPhi * (b - a);
      f2 = cost_at(pairs, samples, x2, bg, nullptr);
    }
  }
  Fit out;
  out.offset_s = 0.5 * (a + b);
  const double cost = cost_at(pairs, samples, out.offset_s, bg, &out.gyro_bias);
  out.rms_rad = std::sqrt(cost / static_cast<double>(pairs.size()));
  return out;
}

}  // namespace orbatlas
