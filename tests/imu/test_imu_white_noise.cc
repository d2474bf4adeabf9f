// The white noise an IMU's samples show (core/imu/white_noise_estimate.h):
// the density a synthetic IMU was made with, found from its samples; the
// increments' chi2 at the true states back at its degrees of freedom for an
// IMU noisier than its settings say; vibration counted only up to the cap;
// and what the real MH_05 recording shows before take-off.
#include <gtest/gtest.h>

#include "core/common/error.h"
#include "core/imu/imu_buffer.h"
#include "core/imu/white_noise_estimate.h"
#include "core/sim/euroc_sequences.h"
#include "core/sim/imu_synthesizer.h"
#include "core/sim/recorded_imu.h"
#include "core/sim/trajectory_spline.h"
#include "tests/support/imu_truth_fit.h"

namespace orbatlas {
namespace {

// MH_01 in flight (60-100 s) with white noise of the given densities and,
// with `vibration`, the real flights' vibration.
sim::SyntheticImu flight_imu(double gyro_density, double accel_density, double vibration) {
  const auto& spline = test::mh01_spline();
  sim::ImuSynthesisOptions o;
  o.seed = 11;
  o.errors.gyro_noise_density = gyro_density;
  o.errors.accel_noise_density = accel_density;
  o.errors.vibration = vibration;
  return sim::synthesize_imu(spline, spline.start_ns() + s_to_ns(60.0), spline.start_ns() + s_to_ns(100.0), o);
}

// The mean chi2 of the true states over intervals of `span_s` (imu_truth_fit.h),
// with the vibration measured and, with `measure_white_noise`, the white noise.
double mean_chi2(const sim::SyntheticImu& imu, double span_s, bool measure_white_noise) {
  ImuBuffer buffer(60.0, true, measure_white_noise);
  buffer.add(imu.samples);
  return test::mean_truth_chi2(imu, buffer, span_s);
}

const ImuNoise kSettings{};  // EuRoC's: 1.6968e-4 rad/s/sqrt(Hz), 2.0e-3 m/s^2/sqrt(Hz)

TEST(WhiteNoiseEstimate, FindsTheDensitiesTheSamplesWereMadeWith) {
  for (const double factor : {1.0, 2.5}) {
    const sim::SyntheticImu imu =
        flight_imu(factor * kSettings.gyro_density, factor * 0.9 * kSettings.accel_density, 0.0);
    double worst_gyro = 0.0, worst_accel = 0.0;
    for (std::size_t k = 400; k < imu.samples.size(); k += 400) {
      const auto d = measure_white_noise(imu.samples, imu.samples[k].t_ns);
      ASSERT_TRUE(d.has_value());
      worst_gyro = std::max(worst_gyro, std::abs(d->gyro / (factor * kSettings.gyro_density) - 1.0));
      worst_accel = std::max(worst_accel, std::abs(d->accel / (factor * 0.9 * kSettings.accel_density) - 1.0));
    }
    EXPECT_LT(worst_gyro, 0.18);   // measured 0.090 (both factors)
    EXPECT_LT(worst_accel, 0.13);  // measured 0.065 and 0.062
  }
}

TEST(WhiteNoiseEstimate, TheIncrementsFitAnImuNoisierThanItsSettings) {
  // The real look's IMU noise (1.6 and 2.25 times the settings'), no vibration.
  const sim::SyntheticImu imu = flight_imu(2.7e-4, 4.5e-3, 0.0);
  const double short_measured = mean_chi2(imu, 0.5, true), short_settings = mean_chi2(imu, 0.5, false);
  EXPECT_GT(short_measured, 3.0);  // measured 4.50
  EXPECT_LT(short_measured, 9.0);
  EXPECT_GT(short_settings, 10.0);  // measured 12.8
  // White noise grows with the interval; vibration's end terms do not.
  const double long_measured = mean_chi2(imu, 2.0, true), long_settings = mean_chi2(imu, 2.0, false);
  EXPECT_GT(long_measured, 4.0);  // measured 7.25
  EXPECT_LT(long_measured, 12.0);
  EXPECT_GT(long_settings, 20.0);  // measured 25.0
}

TEST(WhiteNoiseEstimate, CountsVibrationOnlyUpToTheCap) {
  const sim::SyntheticImu imu = flight_imu(kSettings.gyro_density, kSettings.accel_density, 1.0);
  const TimestampNs t = imu.samples[4000].t_ns;
  const auto d = measure_white_noise(imu.samples, t);
  ASSERT_TRUE(d.has_value());
  EXPECT_GT(d->gyro, 8.0 * kSettings.gyro_density);     // measured 15.5 times
  EXPECT_GT(d->accel, 17.0 * kSettings.accel_density);  // measured 34 times
  const ImuNoise used = with_measured_white_noise(imu.samples, t, kSettings);
  EXPECT_DOUBLE_EQ(used.gyro_density, 3.0 * kSettings.gyro_density);
  EXPECT_DOUBLE_EQ(used.accel_density, 3.0 * kSettings.accel_density);
  // The cap weighs a vibrating IMU a little below what it is worth: the chi2
  // is under its degrees of freedom, but not far.
  const double chi2 = mean_chi2(imu, 0.5, true);
  EXPECT_GT(chi2, 2.5);  // measured 4.09 (5.57 with the settings' white noise)
  EXPECT_LT(chi2, 6.0);
}

TEST(WhiteNoiseEstimate, TheRealMh05RecordingBeforeTakeOff) {
  const auto samples = sim::load_recorded_imu("MH_05", 0, std::numeric_limits<TimestampNs>::max());
  ASSERT_GT(samples.size(), 3000u);
  // Before the motors start (2-12 s): the settings' gyroscope density, the
  // accelerometer's 1.6-2.0 times the settings'.
  for (double at = 2.0; at <= 12.0; at += 2.0) {
    const TimestampNs t = samples.front().t_ns + s_to_ns(at);
    const auto d = measure_white_noise(samples, t);
    ASSERT_TRUE(d.has_value());
    EXPECT_GT(d->gyro, 0.8 * kSettings.gyro_density) << at << " s";  // measured 0.93-1.05 times
    EXPECT_LT(d->gyro, 1.2 * kSettings.gyro_density) << at << " s";
    EXPECT_GT(d->accel, 1.4 * kSettings.accel_density) << at << " s";  // measured 1.6-2.0 times
    EXPECT_LT(d->accel, 2.3 * kSettings.accel_density) << at << " s";
    const ImuNoise used = with_measured_white_noise(samples, t, kSettings);
    EXPECT_EQ(used.gyro_density, std::max(d->gyro, kSettings.gyro_density));
    EXPECT_EQ(used.accel_density, d->accel);
  }
}

TEST(WhiteNoiseEstimate, NothingMeasuredWithoutTheWindowOrOverAGap) {
  const sim::SyntheticImu imu = flight_imu(kSettings.gyro_density, kSettings.accel_density, 0.0);
  // Less than the window before t.
  EXPECT_FALSE(measure_white_noise(imu.samples, imu.samples[300].t_ns).has_value());
  EXPECT_EQ(with_measured_white_noise(imu.samples, imu.samples[300].t_ns, kSettings).gyro_density,
            kSettings.gyro_density);
  // A gap of 100 ms in the window.
  std::vector<ImuSample> gapped = imu.samples;
  gapped.erase(gapped.begin() + 1000, gapped.begin() + 1020);
  EXPECT_FALSE(measure_white_noise(gapped, gapped[1200].t_ns).has_value());
  EXPECT_TRUE(measure_white_noise(gapped, gapped[1500].t_ns).has_value());
  EXPECT_THROW(WhiteNoiseEstimateOptions{.window_s = 0.0}.check(), Error);
  EXPECT_THROW(WhiteNoiseEstimateOptions{.max_factor = 0.5}.check(), Error);
}

}  // namespace
}  // namespace orbatlas
