// IMU preintegration against exact ground truth: noise-free IMU
// synthesised from the real MH_01 trajectory (the simulator's spline) must carry
// the true state of one instant to the true state 0.5-2 s later; the bias
// Jacobians must predict a re-integration with another bias; the propagated
// covariance must match the spread of noisy integrations (Monte Carlo).
#include <gtest/gtest.h>

#include <random>

#include "core/common/error.h"
#include "core/geometry/so3.h"
#include "core/imu/preintegration.h"
#include "core/sim/euroc_sequences.h"
#include "core/sim/imu_synthesizer.h"
#include "core/sim/trajectory_spline.h"

namespace orbatlas {
namespace {

const sim::TrajectorySpline& mh01_spline() {
  static const sim::TrajectorySpline spline(sim::load_ground_truth(sim::find_sequence("MH_01")));
  return spline;
}

const Eigen::Vector3d kGravity(0.0, 0.0, -sim::kGravity);

ImuState state_at(const sim::TrajectorySpline& spline, TimestampNs t) {
  const sim::SplineState s = spline.evaluate(t);  // body = IMU (T_b_i identity)
  return {s.T_w_b.q.toRotationMatrix(), s.T_w_b.t, s.v_w};
}

sim::SyntheticImu ideal_imu(TimestampNs t0, TimestampNs t1) {
  sim::ImuSynthesisOptions options;
  options.add_noise = false;
  return sim::synthesize_imu(mh01_spline(), t0, t1, options);
}

double rotation_error_deg(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return rotation_angle(Eigen::Quaterniond(a.transpose() * b)) * 180.0 / M_PI;
}

TEST(Preintegration, CarriesTheTrueStateToTheTrueStateLater) {
  const auto& spline = mh01_spline();
  double worst_p = 0.0, worst_v = 0.0, worst_deg = 0.0;
  for (const double offset_s : {20.0, 60.0, 110.0}) {
    for (const double span_s : {0.5, 2.0}) {
      // Frame times off the IMU grid: the ends are interpolated.
      const TimestampNs t0 = spline.start_ns() + s_to_ns(offset_s) + 1'234'567;
      const TimestampNs t1 = t0 + s_to_ns(span_s);
      const sim::SyntheticImu imu = ideal_imu(t0 - 20'000'000, t1 + 20'000'000);
      const Preintegration pre = Preintegration::between(imu.samples, t0, t1, ImuBias{}, ImuNoise{});
      EXPECT_NEAR(pre.dt(), span_s, 1e-9);
      const ImuState truth = state_at(spline, t1);
      const ImuState predicted = pre.predict(state_at(spline, t0), ImuBias{}, kGravity);
      worst_p = std::max(worst_p, (predicted.p_w - truth.p_w).norm());
      worst_v = std::max(worst_v, (predicted.v_w - truth.v_w).norm());
      worst_deg = std::max(worst_deg, rotation_error_deg(predicted.R_w_i, truth.R_w_i));
      // The residual of the true states is what the prediction missed.
      const Preintegration::Vector9 r = pre.residual(state_at(spline, t0), truth, ImuBias{}, kGravity);
      EXPECT_LT(r.segment<3>(6).norm(), 2.0 * (predicted.p_w - truth.p_w).norm() + 1e-9);
      EXPECT_LT(pre.residual(state_at(spline, t0), predicted, ImuBias{}, kGravity).norm(), 1e-9);
    }
  }
  EXPECT_LT(worst_p, 2e-4);      // measured 1.0e-4 m (the middle rotation at 200 Hz; the start's: 5.7e-3)
  EXPECT_LT(worst_v, 2e-4);      // measured 8.3e-5 m/s
  EXPECT_LT(worst_deg, 1.5e-3);  // measured 6.9e-4 deg
}

TEST(Preintegration, BiasJacobiansPredictAReintegration) {
  const auto& spline = mh01_spline();
  const TimestampNs t0 = spline.start_ns() + s_to_ns(40.0);
  const TimestampNs t1 = t0 + s_to_ns(1.0);
  const sim::SyntheticImu imu = ideal_imu(t0, t1);
  const ImuBias zero;
  ImuBias bias;  // EuRoC-like magnitudes
  bias.gyro = Eigen::Vector3d(0.004, -0.003, 0.002);
  bias.accel = Eigen::Vector3d(0.03, -0.02, 0.04);
  const Preintegration at_zero = Preintegration::between(imu.samples, t0, t1, zero, ImuNoise{});
  Preintegration exact = at_zero;
  exact.reintegrate(bias);
  const double moved_p = (exact.delta_p() - at_zero.delta_p()).norm();
  const double moved_deg = rotation_error_deg(exact.delta_R(), at_zero.delta_R());
  const double first_order_p = (at_zero.delta_p(bias) - exact.delta_p()).norm();
  const double first_order_v = (at_zero.delta_v(bias) - exact.delta_v()).norm();
  const double first_order_deg = rotation_error_deg(at_zero.delta_R(bias), exact.delta_R());
  ASSERT_GT(moved_p, 1e-2);
  // Second-order terms only: measured 1.0e-3, 1.5e-3 and 1.3e-7 of what the bias moved.
  EXPECT_LT(first_order_p, 2e-3 * moved_p);
  EXPECT_LT(first_order_v, 3e-3 * (exact.delta_v() - at_zero.delta_v()).norm());
  EXPECT_LT(first_order_deg, 3e-7 * moved_deg);
  // Predictions with the bias agree with the truth as well as at zero bias when
  // the measurements carry that bias.
  std::vector<ImuSample> biased = imu.samples;
  for (auto& s : biased) {
    s.gyro += bias.gyro;
    s.accel += bias.accel;
  }
  const Preintegration measured = Preintegration::between(biased, t0, t1, zero, ImuNoise{});
  const ImuState predicted = measured.predict(state_at(spline, t0), bias, kGravity);
  EXPECT_LT((predicted.p_w - state_at(spline, t1).p_w).norm(), 5e-4);
}

// Measurements whose scale factors are off (as a MEMS IMU's are, by tenths of a
// percent), integrated once; the scale correction's first-order Jacobians then
// give the increments of the corrected measurements without integrating again.
TEST(Preintegration, ScaleJacobiansPredictAReintegration) {
  const auto& spline = mh01_spline();
  const TimestampNs t0 = spline.start_ns() + s_to_ns(40.0);
  const TimestampNs t1 = t0 + s_to_ns(1.0);
  const sim::SyntheticImu imu = ideal_imu(t0, t1);
  ImuBias bias;
  bias.gyro = Eigen::Vector3d(0.004, -0.003, 0.002);
  bias.accel = Eigen::Vector3d(0.03, -0.02, 0.04);
  const Eigen::Vector3d gyro_factor(1.003, 0.996, 1.002), accel_factor(0.997, 1.004, 1.003);
  std::vector<ImuSample> measured = imu.samples;  // scaled, then biased
  for (auto& s : measured) {
    s.gyro = gyro_factor.cwiseProduct(s.gyro) + bias.gyro;
    s.accel = accel_factor.cwiseProduct(s.accel) + bias.accel;
  }
  // The correction that undoes the factors: (1 + c) (m - b) is the true value.
  ImuScaleCorrection correction;
  correction.gyro = gyro_factor.cwiseInverse() - Eigen::Vector3d::Ones();
  correction.accel = accel_factor.cwiseInverse() - Eigen::Vector3d::Ones();
  const Preintegration raw = Preintegration::between(measured, t0, t1, bias, ImuNoise{});
  const Preintegration ideal = Preintegration::between(imu.samples, t0, t1, ImuBias{}, ImuNoise{});
  const double moved_p = (raw.delta_p() - ideal.delta_p()).norm();
  const double moved_v = (raw.delta_v() - ideal.delta_v()).norm();
  const double moved_deg = rotation_error_deg(raw.delta_R(), ideal.delta_R());
  ASSERT_GT(moved_p, 1e-3);
  ASSERT_GT(moved_deg, 5e-5);
  // What the factors moved: 15 mm, 29 mm/s and 8e-5 deg over the second; the
  // corrected increments are within 5.5e-7, 7.3e-7 and 1.9e-7 of that (second
  // order: a velocity increment is linear in the specific force).
  EXPECT_LT((raw.delta_p(bias, correction) - ideal.delta_p()).norm(), 1.1e-6 * moved_p);
  EXPECT_LT((raw.delta_v(bias, correction) - ideal.delta_v()).norm(), 1.5e-6 * moved_v);
  EXPECT_LT(rotation_error_deg(raw.delta_R(bias, correction), ideal.delta_R()), 4e-7 * moved_deg);
  // Without the correction the increments stay where the factors moved them.
  EXPECT_NEAR((raw.delta_p(bias) - ideal.delta_p()).norm(), moved_p, 1e-12);
}

TEST(Preintegration, CovarianceMatchesTheSpreadOfNoisyIntegrations) {
  const auto& spline = mh01_spline();
  const TimestampNs t0 = spline.start_ns() + s_to_ns(70.0);
  const TimestampNs t1 = t0 + s_to_ns(0.5);
  const sim::SyntheticImu imu = ideal_imu(t0, t1);
  ImuNoise noise;  // EuRoC's densities, 10x: the spread is then far above discretisation
  noise.gyro_density *= 10.0;
  noise.accel_density *= 10.0;
  const Preintegration clean = Preintegration::between(imu.samples, t0, t1, ImuBias{}, noise);
  std::mt19937_64 rng(7);
  std::normal_distribution<double> unit(0.0, 1.0);
  const int runs = 2000;
  Eigen::Matrix<double, 9, 9> spread = Eigen::Matrix<double, 9, 9>::Zero();
  for (int run = 0; run < runs; ++run) {
    Preintegration noisy(ImuBias{}, noise);
    for (const auto& m : clean.measurements()) {
      const Eigen::Vector3d ng(unit(rng), unit(rng), unit(rng)), na(unit(rng), unit(rng), unit(rng));
      noisy.integrate(m.gyro + std::sqrt(noise.gyro_variance(m.dt)) * ng,
                      m.accel + std::sqrt(noise.accel_variance(m.dt)) * na, m.dt);
    }
    Eigen::Matrix<double, 9, 1> e;
    e.segment<3>(0) = so3_log(Eigen::Quaterniond(clean.delta_R().transpose() * noisy.delta_R()));
    e.segment<3>(3) = noisy.delta_v() - clean.delta_v();
    e.segment<3>(6) = noisy.delta_p() - clean.delta_p();
    spread += e * e.transpose();
  }
  spread /= runs;
  double worst = 0.0;
  for (int i = 0; i < 9; ++i) {
    const double ratio = spread(i, i) / clean.covariance()(i, i);
    worst = std::max(worst, std::abs(ratio - 1.0));
  }
  EXPECT_LT(worst, 0.12);  // 2000 samples: a variance estimate is good to ~3 % (1 sigma)
}

TEST(Preintegration, JoinsAndRefusesWhatItCannotIntegrate) {
  const auto& spline = mh01_spline();
  const TimestampNs t0 = spline.start_ns() + s_to_ns(30.0) + 2'500'000;
  const TimestampNs t1 = t0 + s_to_ns(0.4), t2 = t1 + s_to_ns(0.3);
  const sim::SyntheticImu imu = ideal_imu(t0 - 10'000'000, t2 + 10'000'000);
  // Two consecutive increments joined = one over both.
  Preintegration joined = Preintegration::between(imu.samples, t0, t1, ImuBias{}, ImuNoise{});
  joined.append(Preintegration::between(imu.samples, t1, t2, ImuBias{}, ImuNoise{}));
  const Preintegration whole = Preintegration::between(imu.samples, t0, t2, ImuBias{}, ImuNoise{});
  EXPECT_NEAR(joined.dt(), whole.dt(), 1e-12);
  EXPECT_LT((joined.delta_p() - whole.delta_p()).norm(), 1e-9);
  EXPECT_LT((joined.delta_v() - whole.delta_v()).norm(), 1e-9);
  EXPECT_LT(rotation_error_deg(joined.delta_R(), whole.delta_R()), 1e-7);
  EXPECT_LT((joined.covariance() - whole.covariance()).norm(), 1e-3 * whole.covariance().norm());
  // Outside the samples, across a gap, bad measurements: clear errors.
  EXPECT_THROW(Preintegration::between(imu.samples, t0 - s_to_ns(1.0), t1, ImuBias{}, ImuNoise{}), DataError);
  std::vector<ImuSample> gap = imu.samples;
  gap.erase(gap.begin() + 30, gap.begin() + 60);  // 150 ms missing
  EXPECT_THROW(Preintegration::between(gap, t0, t2, ImuBias{}, ImuNoise{}), DataError);
  // A frame just after the newest sample (a live stream's next batch is on its
  // way): the newest sample holds until it, up to max_gap (50 ms); later, an error.
  std::vector<ImuSample> early;
  for (const ImuSample& s : imu.samples)
    if (s.t_ns <= t1 - 20'000'000) early.push_back(s);
  ASSERT_GT(early.back().t_ns, t1 - 25'000'000);
  const Preintegration held = Preintegration::between(early, t0, t1, ImuBias{}, ImuNoise{});
  EXPECT_NEAR(held.dt(), 0.4, 1e-12);
  const Preintegration exact = Preintegration::between(imu.samples, t0, t1, ImuBias{}, ImuNoise{});
  EXPECT_LT((held.delta_v() - exact.delta_v()).norm(), 0.05);  // 20 ms of one held sample
  EXPECT_GT((held.delta_v() - exact.delta_v()).norm(), 0.0);
  EXPECT_THROW(Preintegration::between(early, t0, t1 + 40'000'000, ImuBias{}, ImuNoise{}), DataError);
  Preintegration p(ImuBias{}, ImuNoise{});
  EXPECT_THROW(p.integrate(Eigen::Vector3d::Constant(std::nan("")), Eigen::Vector3d::Zero(), 0.005), DataError);
  EXPECT_THROW(p.integrate(Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), 0.0), Error);
  ImuNoise bad;
  bad.gyro_density = 0.0;
  EXPECT_THROW(Preintegration(ImuBias{}, bad), Error);
}

}  // namespace
}  // namespace orbatlas
