// The vibration an IMU measures on a flying multirotor, in the increments'
// covariance (core/imu/vibration_estimate.h): the residuals of the true states
// must fit the covariance (their chi2 that of its degrees of freedom) with the
// real flights' vibration, which the white-noise model alone is far from; an
// IMU without vibration measures (almost) none.
#include <gtest/gtest.h>

#include "core/imu/imu_buffer.h"
#include "core/imu/vibration_estimate.h"
#include "core/sim/euroc_sequences.h"
#include "core/sim/imu_synthesizer.h"
#include "core/sim/trajectory_spline.h"
#include "tests/support/imu_truth_fit.h"

namespace orbatlas {
namespace {

// MH_01 in flight (60-120 s), the settings' white noise and, with
// `vibration`, the real flights' vibration.
sim::SyntheticImu flight_imu(double vibration) {
  const auto& spline = test::mh01_spline();
  sim::ImuSynthesisOptions o;
  o.seed = 5;
  o.errors.vibration = vibration;
  return sim::synthesize_imu(spline, spline.start_ns() + s_to_ns(60.0), spline.start_ns() + s_to_ns(120.0), o);
}

// The mean chi2 of the true states over intervals of `span_s` (imu_truth_fit.h),
// with the settings' white noise and, with `measure_vibration`, the vibration
// measured.
double mean_chi2(const sim::SyntheticImu& imu, double span_s, bool measure_vibration) {
  ImuBuffer buffer(60.0, measure_vibration, /*measure_white_noise=*/false);
  buffer.add(imu.samples);
  return test::mean_truth_chi2(imu, buffer, span_s);
}

TEST(VibrationEstimate, TheIncrementsCovarianceFitsTheFlightsVibration) {
  const sim::SyntheticImu shaking = flight_imu(1.0);
  for (const double span_s : {0.05, 0.5}) {
    const double measured = mean_chi2(shaking, span_s, true), white = mean_chi2(shaking, span_s, false);
    EXPECT_GT(measured, 3.0);  // measured 6.6 (0.05 s) and 5.3 (0.5 s)
    EXPECT_LT(measured, 12.0);
    EXPECT_GT(white, 60.0) << "the white-noise model alone should not fit a vibrating IMU";
  }
  // What it measured in flight: about a milliradian and 5 mm/s per axis.
  ImuBuffer buffer(30.0, true, /*measure_white_noise=*/false);
  buffer.add(shaking.samples);
  const ImuVibration v = buffer.measured(shaking.samples[6000].t_ns, ImuNoise{}).vibration;
  EXPECT_GT(std::sqrt(v.rotation_var.maxCoeff()), 3e-4);
  EXPECT_LT(std::sqrt(v.rotation_var.maxCoeff()), 3e-3);
  EXPECT_GT(std::sqrt(v.velocity_var.maxCoeff()), 2e-3);
  EXPECT_LT(std::sqrt(v.velocity_var.maxCoeff()), 2e-2);
}

TEST(VibrationEstimate, AnIdealImuMeasuresNone) {
  const sim::SyntheticImu calm = flight_imu(0.0);
  ImuBuffer buffer(30.0, true, /*measure_white_noise=*/false);
  buffer.add(calm.samples);
  double worst_rotation = 0.0, worst_velocity = 0.0;
  for (std::size_t k = 600; k < calm.samples.size(); k += 200) {
    const ImuVibration v = buffer.measured(calm.samples[k].t_ns, ImuNoise{}).vibration;
    worst_rotation = std::max(worst_rotation, std::sqrt(v.rotation_var.maxCoeff()));
    worst_velocity = std::max(worst_velocity, std::sqrt(v.velocity_var.maxCoeff()));
  }
  // What it takes for vibration is the trajectory's own motion above the corner.
  EXPECT_LT(worst_rotation, 6e-4);    // measured 3.3e-4 rad
  EXPECT_LT(worst_velocity, 3.5e-3);  // measured 1.7e-3 m/s
  // The model fits that IMU nearly as the white noise alone does.
  const double chi2 = mean_chi2(calm, 0.5, true);
  EXPECT_GT(chi2, 3.0);
  EXPECT_LT(chi2, 10.0);
  // Too few samples, or a gap: nothing measured.
  EXPECT_EQ(estimate_vibration({calm.samples.begin(), calm.samples.begin() + 30}, calm.samples[29].t_ns, ImuNoise{}),
            ImuVibration{});
}

}  // namespace
}  // namespace orbatlas
