// The session's IMU buffer: the mean specific force over a window up to a
// camera time (what a new map is levelled by), against the exact mean of the
// samples it covers.
#include <gtest/gtest.h>

#include "core/imu/imu_buffer.h"

namespace orbatlas {
namespace {

constexpr TimestampNs kStart = 1'000'000'000;
constexpr TimestampNs kStep = 5'000'000;  // 200 Hz

// 400 samples (2 s) into `buffer`, sample k reading accel (k, 2k, 9.81).
void fill_ramp(ImuBuffer& buffer) {
  std::vector<ImuSample> samples;
  for (int k = 0; k < 400; ++k) {
    ImuSample s;
    s.t_ns = kStart + k * kStep;
    s.accel = Eigen::Vector3d(k, 2.0 * k, 9.81);
    samples.push_back(s);
  }
  buffer.add(samples);
}

TEST(ImuBuffer, MeanAccelIsTheMeanOfTheSamplesInTheWindow) {
  ImuBuffer buffer;
  fill_ramp(buffer);
  // Up to sample 299, half a second: samples 199..299 (both ends in), mean k = 249.
  const auto mean = buffer.mean_accel(kStart + 299 * kStep, 0.5, 3);
  ASSERT_TRUE(mean.has_value());
  EXPECT_NEAR(mean->x(), 249.0, 1e-9);
  EXPECT_NEAR(mean->y(), 498.0, 1e-9);
  EXPECT_NEAR(mean->z(), 9.81, 1e-12);
}

TEST(ImuBuffer, MeanAccelFollowsTheCamerasClockOffset) {
  ImuBuffer buffer;
  fill_ramp(buffer);
  // An image stamped t was taken at IMU time t + 50 ms: ten samples later.
  buffer.set_time_offset(50'000'000);
  const auto mean = buffer.mean_accel(kStart + 289 * kStep, 0.5, 3);
  ASSERT_TRUE(mean.has_value());
  EXPECT_NEAR(mean->x(), 249.0, 1e-9);
}

TEST(ImuBuffer, MeanAccelNeedsItsSamples) {
  ImuBuffer buffer;
  fill_ramp(buffer);
  // Before the first sample: none; just after it: two samples.
  EXPECT_FALSE(buffer.mean_accel(kStart - kStep, 0.5, 1).has_value());
  EXPECT_FALSE(buffer.mean_accel(kStart + kStep, 0.5, 3).has_value());
  const auto two = buffer.mean_accel(kStart + kStep, 0.5, 2);
  ASSERT_TRUE(two.has_value());
  EXPECT_NEAR(two->x(), 0.5, 1e-12);
  EXPECT_FALSE(ImuBuffer().mean_accel(kStart, 0.5, 1).has_value());
}

}  // namespace
}  // namespace orbatlas
