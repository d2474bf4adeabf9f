// Whether a map's IMU still agrees with its vision (core/mapping/inertial_consistency.h):
// the median of the latest local BAs' median inertial chi2 against the bound,
// a reset, then giving up after max_resets.
#include <gtest/gtest.h>

#include <limits>

#include "core/common/error.h"
#include "core/mapping/inertial_consistency.h"

namespace orbatlas {
namespace {

using Verdict = InertialConsistency::Verdict;

TEST(InertialConsistency, AConsistentImuIsKeptAndOneBadBaIsNotEnough) {
  InertialConsistency c;
  // A consistent IMU: medians about 3 (the realistic IMU on MH_01: p50 2.7).
  for (int i = 0; i < 50; ++i) EXPECT_EQ(c.add(0, 3.0 + (i % 3)), Verdict::kKeep);
  // Two bad BAs among five: the median stays low.
  EXPECT_EQ(c.add(0, 500.0), Verdict::kKeep);
  EXPECT_EQ(c.add(0, 500.0), Verdict::kKeep);
  EXPECT_EQ(c.add(0, 3.0), Verdict::kKeep);
  EXPECT_NEAR(c.recent_median(0), 4.0, 1e-12);
  EXPECT_FALSE(c.given_up(0));
}

TEST(InertialConsistency, ADisagreeingImuIsResetTwiceThenGivenUp) {
  InertialConsistencyOptions o;
  InertialConsistency c(o);
  int resets = 0, give_ups = 0;
  for (int i = 0; i < 40; ++i) {
    const Verdict v = c.add(7, 80.0);  // an accelerometer bias that jumped by 0.5 m/s^2: medians 10-1700
    resets += v == Verdict::kReset;
    give_ups += v == Verdict::kGiveUp;
  }
  EXPECT_EQ(resets, 2);
  EXPECT_EQ(give_ups, 1);
  EXPECT_TRUE(c.given_up(7));
  EXPECT_FALSE(c.given_up(8)) << "per map";
  // Three bad BAs of five reset.
  InertialConsistency d(o);
  EXPECT_EQ(d.add(1, 3.0), Verdict::kKeep);
  EXPECT_EQ(d.add(1, 3.0), Verdict::kKeep);
  EXPECT_EQ(d.add(1, 31.0), Verdict::kKeep);
  EXPECT_EQ(d.add(1, 31.0), Verdict::kKeep);
  EXPECT_EQ(d.add(1, 31.0), Verdict::kReset);
  EXPECT_EQ(d.recent_median(1), 0.0) << "a reset starts the window again";
  // A BA whose chi2 could not be evaluated counts as the worst.
  for (int i = 0; i < 4; ++i) EXPECT_EQ(d.add(2, std::numeric_limits<double>::infinity()), Verdict::kKeep);
  EXPECT_EQ(d.add(2, std::numeric_limits<double>::quiet_NaN()), Verdict::kReset);
}

TEST(InertialConsistency, OffKeepsEverythingAndOptionsCheckThemselves) {
  InertialConsistencyOptions o;
  o.enabled = false;
  InertialConsistency c(o);
  for (int i = 0; i < 20; ++i) EXPECT_EQ(c.add(0, 1e6), Verdict::kKeep);
  o = {};
  o.window = 0;
  EXPECT_THROW(o.check(), Error);
  o = {};
  o.max_median_chi2 = 0.0;
  EXPECT_THROW(o.check(), Error);
}

}  // namespace
}  // namespace orbatlas
