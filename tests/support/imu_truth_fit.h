#pragma once
// How well an IMU's increments fit the true trajectory: the residuals of the
// true states under the increments' covariance, for the IMU tests that check
// a noise model (vibration, white noise) against synthetic samples of MH_01.
#include <gtest/gtest.h>

#include "core/imu/imu_buffer.h"
#include "core/sim/euroc_sequences.h"
#include "core/sim/imu_synthesizer.h"
#include "core/sim/trajectory_spline.h"

namespace orbatlas::test {

inline const sim::TrajectorySpline& mh01_spline() {
  static const sim::TrajectorySpline spline(sim::load_ground_truth(sim::find_sequence("MH_01")));
  return spline;
}

// The IMU's state on MH_01's spline at t (body = IMU, T_b_i identity).
inline ImuState mh01_state(TimestampNs t) {
  const sim::SplineState s = mh01_spline().evaluate(t);
  return {s.T_w_b.q.toRotationMatrix(), s.T_w_b.t, s.v_w};
}

// The mean chi2 of the rotation and velocity residuals (6 degrees of freedom)
// of the true states at the true biases, over intervals of `span_s` starting
// every 0.5 s from the samples' fourth second, with the increments `buffer`
// makes of `imu` (synthesised on MH_01's spline) and the settings' noise.
inline double mean_truth_chi2(const sim::SyntheticImu& imu, const ImuBuffer& buffer, double span_s) {
  double sum = 0.0;
  int n = 0;
  for (std::size_t k = 600; k + 200 * span_s + 10 < imu.samples.size(); k += 100) {
    const TimestampNs t0 = imu.samples[k].t_ns + 1'234'567, t1 = t0 + s_to_ns(span_s);
    const ImuBias bias{imu.states[k].gyro_bias, imu.states[k].accel_bias};
    const auto pre = buffer.between(t0, t1, bias, ImuNoise{});
    EXPECT_TRUE(pre.has_value());
    if (!pre) continue;
    const Preintegration::Vector9 r =
        pre->residual(mh01_state(t0), mh01_state(t1), bias, Eigen::Vector3d(0.0, 0.0, -sim::kGravity));
    const Eigen::Matrix<double, 6, 6> c = pre->covariance().topLeftCorner<6, 6>();
    sum += r.head<6>().dot(c.ldlt().solve(r.head<6>()));
    ++n;
  }
  return sum / n;
}

}  // namespace orbatlas::test
