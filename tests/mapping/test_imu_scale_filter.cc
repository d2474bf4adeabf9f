// The map's IMU scale estimate fused from windows in information form, against
// the exact information-weighted means.
#include <gtest/gtest.h>

#include "core/common/error.h"
#include "core/mapping/imu_scale_filter.h"

namespace orbatlas {
namespace {

ImuScaleInformation accel_z_only(double information) {
  ImuScaleInformation info = ImuScaleInformation::Zero();
  info(5, 5) = information;
  return info;
}

TEST(ImuScaleFilter, WeighsEachWindowByWhatItSawAndKeepsThePriorWhereItSawNothing) {
  ImuScaleFilter filter(ImuScaleFilterOptions{.prior_sigma = 0.01, .overlap = 1.0});
  const MapId map{3};
  // A window that saw the accelerometer's z axis only (information 1e6, sigma
  // 0.001) and says 0.003 there; on the other axes it says nonsense it has no
  // information on.
  ImuScaleCorrection window;
  window.gyro = Eigen::Vector3d(0.02, -0.02, 0.02);
  window.accel = Eigen::Vector3d(0.02, -0.02, 0.003);
  ImuScaleCorrection estimate = filter.add(map, {}, window, accel_z_only(1e6));
  // The prior's 1e4 about none against the window's 1e6 about 0.003.
  EXPECT_NEAR(estimate.accel.z(), 1e6 * 0.003 / (1e6 + 1e4), 1e-15);
  EXPECT_EQ(estimate.gyro, Eigen::Vector3d::Zero());
  EXPECT_EQ(estimate.accel.head<2>(), Eigen::Vector2d::Zero());
  // A second window adds its information to the first's.
  const double first = estimate.accel.z();
  estimate = filter.add(map, estimate, window, accel_z_only(1e6));
  EXPECT_NEAR(estimate.accel.z(), ((1e6 + 1e4) * first + 1e6 * 0.003) / (2e6 + 1e4), 1e-15);
  EXPECT_DOUBLE_EQ(filter.information(map)(5, 5), 2e6 + 1e4);
  EXPECT_DOUBLE_EQ(filter.information(map)(0, 0), 1e4);
  // Another map is apart; a dropped map starts from the prior.
  EXPECT_DOUBLE_EQ(filter.information(MapId{4})(5, 5), 1e4);
  filter.forget(map);
  EXPECT_DOUBLE_EQ(filter.information(map)(5, 5), 1e4);
}

TEST(ImuScaleFilter, SharesAWindowsInformationWithTheWindowsItsLinksAreInAndStaysInBounds) {
  ImuScaleFilter filter(ImuScaleFilterOptions{.prior_sigma = 0.01, .overlap = 10.0});
  const MapId map{1};
  ImuScaleCorrection window;
  window.accel.z() = 0.003;
  const ImuScaleCorrection estimate = filter.add(map, {}, window, accel_z_only(1e6));
  EXPECT_NEAR(estimate.accel.z(), 1e5 * 0.003 / (1e5 + 1e4), 1e-15);
  // A window far past any IMU's tolerance moves the estimate to the bound, no further.
  window.accel.z() = 0.5;
  EXPECT_DOUBLE_EQ(filter.add(map, estimate, window, accel_z_only(1e12)).accel.z(), 0.05);
  // Not finite: the estimate stays.
  window.accel.z() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(filter.add(map, estimate, window, accel_z_only(1e6)), estimate);
  EXPECT_THROW(ImuScaleFilter(ImuScaleFilterOptions{.prior_sigma = 0.0}), Error);
  EXPECT_THROW(ImuScaleFilter(ImuScaleFilterOptions{.overlap = 0.5}), Error);
}

}  // namespace
}  // namespace orbatlas
