// What an IMU stream may not carry into the estimator (core/imu/imu_input_check.h):
// each kind of bad sample dropped and counted, each kind warned of once, the
// stream's gaps and rate measured, frames outside the IMU's stamps seen.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "core/common/error.h"
#include "core/imu/imu_input_check.h"

namespace orbatlas {
namespace {

// `n` samples at `rate_hz` from t0 with white noise on every axis (a real sensor's).
std::vector<ImuSample> noisy_stream(std::size_t n, double rate_hz = 200.0, TimestampNs t0 = 1'000'000'000,
                                    unsigned seed = 3) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 0.003), a(0.0, 0.03);
  std::vector<ImuSample> out(n);
  for (std::size_t i = 0; i < n; ++i) {
    out[i].t_ns = t0 + static_cast<TimestampNs>(std::llround(static_cast<double>(i) * 1e9 / rate_hz));
    out[i].gyro = Eigen::Vector3d(0.1 + g(rng), g(rng), g(rng));
    out[i].accel = Eigen::Vector3d(a(rng), a(rng), 9.81 + a(rng));
  }
  return out;
}

TEST(ImuInputCheck, AClean200HzStreamPassesWhole) {
  ImuInputCheck check;
  const auto stream = noisy_stream(1000);
  EXPECT_EQ(check.filter(stream).size(), stream.size());
  const auto h = check.health();
  EXPECT_TRUE(h.clean());
  EXPECT_EQ(h.accepted, 1000u);
  ASSERT_TRUE(h.rate_hz.has_value());
  EXPECT_NEAR(*h.rate_hz, 200.0, 0.01);
}

TEST(ImuInputCheck, BadSamplesAreDroppedCountedAndWarnedOfOnce) {
  ImuInputCheckOptions options;
  options.gyro_range = 8.7;  // 500 degrees/s
  ImuInputCheck check(options);
  std::vector<std::string> logged;
  check.set_warning_sink([&](const std::string& w) { logged.push_back(w); });
  auto stream = noisy_stream(1000);
  stream[10].gyro.x() = std::numeric_limits<double>::quiet_NaN();
  stream[11].accel.z() = std::numeric_limits<double>::infinity();
  for (std::size_t i = 100; i < 180; ++i) stream[i].accel.y() = 0.25;  // stuck for 80 samples
  for (std::size_t i = 300; i < 305; ++i) stream[i].gyro.z() = 8.7;    // saturated
  const auto kept = check.filter(stream);
  const auto h = check.health();
  EXPECT_EQ(h.non_finite, 2u);
  EXPECT_EQ(h.saturated, 5u);
  // The run is stuck from its 50th sample on: 31 dropped (the first 49 could not be told yet).
  EXPECT_EQ(h.stuck, 31u);
  EXPECT_EQ(kept.size(), 1000u - 2 - 5 - 31);
  EXPECT_EQ(h.accepted, kept.size());
  ASSERT_EQ(h.warnings.size(), 3u);
  EXPECT_EQ(logged, h.warnings);
  EXPECT_NE(h.warnings[0].find("not a finite number"), std::string::npos) << h.warnings[0];
  EXPECT_NE(h.warnings[1].find("stuck"), std::string::npos) << h.warnings[1];
  EXPECT_NE(h.warnings[2].find("gyro saturated"), std::string::npos) << h.warnings[2];
  for (const auto& s : kept) EXPECT_TRUE(s.gyro.allFinite() && s.accel.allFinite());

  // The same faults again: counted, not warned of again.
  auto more = noisy_stream(200, 200.0, stream.back().t_ns + 5'000'000, 7);
  more[5].gyro.y() = std::numeric_limits<double>::quiet_NaN();
  check.filter(more);
  EXPECT_EQ(check.health().non_finite, 3u);
  EXPECT_EQ(check.health().warnings.size(), 3u);
}

TEST(ImuInputCheck, ASensorWithoutNoiseIsNotStuck) {
  // A test's noiseless IMU: all three axes of each sensor constant.
  std::vector<ImuSample> still(400);
  for (std::size_t i = 0; i < still.size(); ++i) {
    still[i].t_ns = 1'000'000'000 + static_cast<TimestampNs>(i) * 5'000'000;
    still[i].accel = Eigen::Vector3d(0.0, 0.0, 9.81);
  }
  ImuInputCheck check;
  EXPECT_EQ(check.filter(still).size(), still.size());
  EXPECT_TRUE(check.health().clean());
}

TEST(ImuInputCheck, GapsAndTheRateAreMeasured) {
  ImuInputCheck check;
  auto first = noisy_stream(300, 100.0);  // half the settings' rate
  auto after_gap = noisy_stream(300, 100.0, first.back().t_ns + 400'000'000, 5);
  check.filter(first);
  check.filter(after_gap);
  const auto h = check.health();
  EXPECT_EQ(h.gaps, 1u);
  EXPECT_NEAR(h.longest_gap_s, 0.4, 1e-9);
  ASSERT_TRUE(h.rate_hz.has_value());
  EXPECT_NEAR(*h.rate_hz, 100.0, 0.01);
  ASSERT_EQ(h.warnings.size(), 2u);
  EXPECT_NE(h.warnings[0].find("IMU runs at 100.0 Hz, the settings say 200.0 Hz"), std::string::npos) << h.warnings[0];
  EXPECT_NE(h.warnings[1].find("IMU gap of 400 ms"), std::string::npos) << h.warnings[1];
  EXPECT_EQ(h.accepted, 600u);  // a gap drops nothing
}

TEST(ImuInputCheck, ASampleBeforeThePreviousRefusesTheWholeBatch) {
  ImuInputCheck check;
  check.filter(noisy_stream(10));
  auto batch = noisy_stream(10, 200.0, 2'000'000'000);
  batch[4].t_ns = batch[3].t_ns;
  EXPECT_THROW(check.filter(batch), DataError);
  EXPECT_EQ(check.health().accepted, 10u);
  batch[4].t_ns = batch[3].t_ns + 1;
  EXPECT_EQ(check.filter(batch).size(), 10u);  // the batch fixed is taken
}

TEST(ImuInputCheck, FramesOutsideTheImusStampsAreCounted) {
  ImuInputCheck check;
  check.check_frame(0);             // no IMU yet: nothing to say
  check.filter(noisy_stream(400));  // 1.0 to 3.0 s
  check.check_frame(2'000'000'000);
  check.check_frame(3'400'000'000);  // 0.4 s after the last sample: within 0.5 s
  EXPECT_TRUE(check.health().clean());
  check.check_frame(13'000'000'000);                 // a camera clock 10 s ahead
  check.check_frame(2'000'000'000, 11'000'000'000);  // or an offset that moves it so
  const auto h = check.health();
  EXPECT_EQ(h.frames_outside, 2u);
  ASSERT_EQ(h.warnings.size(), 1u);
  EXPECT_NE(h.warnings[0].find("after the last IMU sample"), std::string::npos) << h.warnings[0];
}

TEST(ImuInputCheck, OptionsCheckThemselves) {
  ImuInputCheckOptions o;
  EXPECT_NO_THROW(o.check());
  o.rate_hz = 0.0;
  EXPECT_THROW(o.check(), Error);
  o = {};
  o.stuck_samples = 1;
  EXPECT_THROW(o.check(), Error);
  o = {};
  o.gyro_range = std::nan("");
  EXPECT_THROW(o.check(), Error);
  o = {};
  o.max_gap_s = -1.0;
  EXPECT_THROW(o.check(), Error);
}

}  // namespace
}  // namespace orbatlas
