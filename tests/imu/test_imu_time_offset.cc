// The camera-IMU clock offset from the gyro against the images' rotation
// (core/imu/time_offset_estimate.h), on MH_01's real trajectory in flight with
// the realistic IMU (the real flights' vibration, biases, noise): frames at 20
// Hz whose rotations carry a visual pose's error.
#include <gtest/gtest.h>

#include <random>

#include "core/geometry/so3.h"
#include "core/imu/time_offset_estimate.h"
#include "core/sim/euroc_sequences.h"
#include "core/sim/imu_synthesizer.h"
#include "core/sim/trajectory_spline.h"

namespace orbatlas {
namespace {

const sim::TrajectorySpline& mh01_spline() {
  static const sim::TrajectorySpline spline(sim::load_ground_truth(sim::find_sequence("MH_01")));
  return spline;
}

// `seconds` of MH_01 from `from_s`: the realistic IMU late by `offset_s`, and the
// frames' IMU rotations with 0.3 mrad of error each.
struct Recording {
  std::vector<ImuSample> imu;
  std::vector<ImuTimeOffset::Frame> frames;
};
Recording record(double from_s, double offset_s, double seconds = 12.0) {
  const auto& spline = mh01_spline();
  sim::ImuSynthesisOptions o;
  o.seed = 21;
  o.errors = sim::realistic_imu_errors();
  o.errors.time_offset_s = offset_s;
  const TimestampNs t0 = spline.start_ns() + s_to_ns(from_s);
  Recording r;
  r.imu = sim::synthesize_imu(spline, t0 - kNsPerSecond, t0 + s_to_ns(seconds + 1.0), o).samples;
  std::mt19937_64 rng(4);
  std::normal_distribution<double> n(0.0, 3e-4);
  for (TimestampNs t = t0; t < t0 + s_to_ns(seconds); t += 50'000'000)
    r.frames.push_back({t, spline.pose(t).q * so3_exp(Eigen::Vector3d(n(rng), n(rng), n(rng)))});
  return r;
}

TEST(ImuTimeOffset, AWindowFindsTheOffsetOfTheImusClock) {
  ImuTimeOffsetOptions options;
  options.window_s = 12.0;
  for (const double offset_ms : {0.0, 5.0, -8.0}) {
    const Recording r = record(60.0, offset_ms * 1e-3);
    const auto fit = ImuTimeOffset::fit(r.frames, r.imu, options);
    ASSERT_TRUE(fit.has_value()) << offset_ms;
    // The vibration's part of one 12-s window: 0.27-0.51 ms (none without it: 0.03 ms).
    EXPECT_NEAR(fit->offset_s * 1e3, offset_ms, 1.0) << fit->rms_rad * 1e3 << " mrad per pair";
    // The realistic IMU's gyro bias, around the real device's (-0.002, 0.022, 0.078).
    EXPECT_NEAR(fit->gyro_bias.z(), 0.078, 0.01);
  }
}

TEST(ImuTimeOffset, TheSessionsEstimateComesFromSeveralWindowsAndNotFromAStillRig) {
  // Parked on the floor (MH_01 20-32 s): nothing turns, no estimate.
  ImuTimeOffsetOptions options;
  const Recording still = record(20.0, 0.005);
  EXPECT_FALSE(ImuTimeOffset::fit(still.frames, still.imu, options).has_value());

  const Recording r = record(60.0, 0.005, 20.0);
  ImuTimeOffset estimate(options);
  for (const auto& f : r.frames) {
    estimate.add_frame(f.t_ns, f.q_w_i);
    estimate.update(r.imu);
  }
  ASSERT_TRUE(estimate.offset_s().has_value()) << estimate.windows() << " windows";
  EXPECT_NEAR(*estimate.offset_s() * 1e3, 5.0, 1.0) << estimate.windows() << " windows";
  estimate.reset();
  EXPECT_TRUE(estimate.offset_s().has_value()) << "a new map keeps what the session knows of its clock";
}

TEST(ImuTimeOffset, PairsAcrossAJumpOfTheMapAreLeftOut) {
  // The map turned by 110 degrees (its gravity alignment) 4 s into the
  // window, and moved by 20 mrad (a loop correction) 8 s in.
  Recording r = record(60.0, 0.005);
  const Eigen::Quaterniond turn = so3_exp(Eigen::Vector3d(1.9, 0.3, 0.0));
  const Eigen::Quaterniond nudge = so3_exp(Eigen::Vector3d(0.0, 0.02, 0.0));
  for (auto& f : r.frames) {
    const double s = ns_to_s(f.t_ns - r.frames.front().t_ns);
    if (s >= 4.0) f.q_w_i = turn * f.q_w_i;
    if (s >= 8.0) f.q_w_i = nudge * f.q_w_i;
  }
  ImuTimeOffsetOptions options;
  options.window_s = 12.0;
  const auto fit = ImuTimeOffset::fit(r.frames, r.imu, options);
  ASSERT_TRUE(fit.has_value());
  EXPECT_NEAR(fit->offset_s * 1e3, 5.0, 1.0);
}

}  // namespace
}  // namespace orbatlas
