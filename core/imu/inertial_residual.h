#pragma once
// The inertial residual of two IMU states (rotation, velocity, position: zero
// when they agree with the increments corrected to the biases to first order),
// templated on the scalar so that Ceres differentiates it automatically; the
// one formula behind Preintegration::residual, the inertial initialisation and
// the visual-inertial costs. Also the SO(3) exponential and logarithm for any
// scalar, and the whitening of a covariance.
#include <ceres/rotation.h>

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include "core/common/error.h"
#include "core/imu/preintegration.h"

namespace orbatlas {

template <typename T>
using Vec3T = Eigen::Matrix<T, 3, 1>;
template <typename T>
using Mat3T = Eigen::Matrix<T, 3, 3>;

template <typename T>
Mat3T<T> so3_exp_t(const Vec3T<T>& w) {
  Mat3T<T> R;
  ceres::AngleAxisToRotationMatrix(w.data(), R.data());  // column-major, as Eigen stores it
  return R;
}

template <typename T>
Vec3T<T> so3_log_t(const Mat3T<T>& R) {
  Vec3T<T> w;
  ceres::RotationMatrixToAngleAxis(R.data(), w.data());
  return w;
}

// States (R_w_i, p_w, v_w) at the increments' two ends, the biases (gyro,
// accel), gravity in the world and a correction of the scale factors (gyro,
// accel; ImuScaleCorrection).
template <typename T>
Eigen::Matrix<T, 9, 1> inertial_residual(const Preintegration& d, const Mat3T<T>& R1, const Vec3T<T>& p1,
                                         const Vec3T<T>& v1, const Mat3T<T>& R2, const Vec3T<T>& p2, const Vec3T<T>& v2,
                                         const Vec3T<T>& bg, const Vec3T<T>& ba, const Vec3T<T>& g, const Vec3T<T>& sg,
                                         const Vec3T<T>& sa) {
  const Vec3T<T> dbg = bg - d.bias().gyro.cast<T>(), dba = ba - d.bias().accel.cast<T>();
  const Mat3T<T> dR =
      d.delta_R().cast<T>() * so3_exp_t<T>(Vec3T<T>(d.dR_dbg().cast<T>() * dbg + d.dR_dsg().cast<T>() * sg));
  const Vec3T<T> dv = d.delta_v().cast<T>() + d.dv_dbg().cast<T>() * dbg + d.dv_dba().cast<T>() * dba +
                      d.dv_dsg().cast<T>() * sg + d.dv_dsa().cast<T>() * sa;
  const Vec3T<T> dp = d.delta_p().cast<T>() + d.dp_dbg().cast<T>() * dbg + d.dp_dba().cast<T>() * dba +
                      d.dp_dsg().cast<T>() * sg + d.dp_dsa().cast<T>() * sa;
  const T dt(d.dt());
  const Mat3T<T> R1t = R1.transpose();
  Eigen::Matrix<T, 9, 1> r;
  r.template segment<3>(0) = so3_log_t<T>(Mat3T<T>(dR.transpose() * R1t * R2));
  r.template segment<3>(3) = R1t * (v2 - v1 - g * dt) - dv;
  r.template segment<3>(6) = R1t * (p2 - p1 - v1 * dt - T(0.5) * g * dt * dt) - dp;
  return r;
}

// The same with the scale factors as integrated (no correction).
template <typename T>
Eigen::Matrix<T, 9, 1> inertial_residual(const Preintegration& d, const Mat3T<T>& R1, const Vec3T<T>& p1,
                                         const Vec3T<T>& v1, const Mat3T<T>& R2, const Vec3T<T>& p2, const Vec3T<T>& v2,
                                         const Vec3T<T>& bg, const Vec3T<T>& ba, const Vec3T<T>& g) {
  const Vec3T<T> zero = Vec3T<T>::Zero();
  return inertial_residual<T>(d, R1, p1, v1, R2, p2, v2, bg, ba, g, zero, zero);
}

// W with |W r|^2 = r^T covariance^-1 r (W = C^-1 for covariance = C C^T).
// Throws Error when the covariance is not positive definite.
template <int N>
Eigen::Matrix<double, N, N> whitening(const Eigen::Matrix<double, N, N>& covariance) {
  const Eigen::Matrix<double, N, N> symmetric = 0.5 * (covariance + covariance.transpose());
  const Eigen::LLT<Eigen::Matrix<double, N, N>> llt(symmetric);
  ORBATLAS_CHECK(covariance.allFinite() && llt.info() == Eigen::Success,
                 "whitening: the covariance is not positive definite");
  const Eigen::Matrix<double, N, N> C = llt.matrixL();
  return C.inverse();
}

}  // namespace orbatlas
