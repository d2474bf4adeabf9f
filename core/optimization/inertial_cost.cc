#include "core/optimization/inertial_cost.h"

#include <ceres/autodiff_cost_function.h>
#include <ceres/normal_prior.h>
#include <ceres/rotation.h>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include "core/common/error.h"

namespace orbatlas {
namespace {

template <typename T>
using Vec3 = Eigen::Matrix<T, 3, 1>;
template <typename T>
using Mat3 = Eigen::Matrix<T, 3, 3>;

template <typename T>
Mat3<T> exp_so3(const Vec3<T>& w) {
  Mat3<T> R;
  ceres::AngleAxisToRotationMatrix(w.data(), R.data());  // column-major, as Eigen stores it
  return R;
}

template <typename T>
Vec3<T> log_so3(const Mat3<T>& R) {
  Vec3<T> w;
  ceres::RotationMatrixToAngleAxis(R.data(), w.data());
  return w;
}

// The IMU's pose in the world from the camera pose T_c_w: T_w_i = T_c_w^-1 * T_c_i.
template <typename T>
void imu_pose(const T* q_c_w, const T* t_c_w, const Eigen::Matrix3d& R_c_i, const Eigen::Vector3d& t_c_i,
              Mat3<T>& R_w_i, Vec3<T>& p_w_i) {
  const Eigen::Map<const Eigen::Quaternion<T>> q(q_c_w);
  const Eigen::Map<const Vec3<T>> t(t_c_w);
  const Mat3<T> R_w_c = q.conjugate().toRotationMatrix();
  R_w_i = R_w_c * R_c_i.cast<T>();
  p_w_i = R_w_c * (t_c_i.cast<T>() - t);
}

struct InertialResidual {
  std::shared_ptr<const Preintegration> increments;
  Eigen::Matrix3d R_c_i;
  Eigen::Vector3d t_c_i, gravity_w;
  Eigen::Matrix<double, 9, 9> weight;  // square root of the information

  template <typename T>
  bool operator()(const T* q1, const T* t1, const T* v1, const T* q2, const T* t2, const T* v2, const T* bias,
                  T* out) const {
    const Preintegration& d = *increments;
    Mat3<T> R1, R2;
    Vec3<T> p1, p2;
    imu_pose(q1, t1, R_c_i, t_c_i, R1, p1);
    imu_pose(q2, t2, R_c_i, t_c_i, R2, p2);
    const Eigen::Map<const Vec3<T>> vel1(v1), vel2(v2);
    const Vec3<T> dbg = Eigen::Map<const Vec3<T>>(bias) - d.bias().gyro.cast<T>();
    const Vec3<T> dba = Eigen::Map<const Vec3<T>>(bias + 3) - d.bias().accel.cast<T>();
    // The increments corrected to the bias, to first order.
    const Mat3<T> dR = d.delta_R().cast<T>() * exp_so3<T>(d.dR_dbg().cast<T>() * dbg);
    const Vec3<T> dv = d.delta_v().cast<T>() + d.dv_dbg().cast<T>() * dbg + d.dv_dba().cast<T>() * dba;
    const Vec3<T> dp = d.delta_p().cast<T>() + d.dp_dbg().cast<T>() * dbg + d.dp_dba().cast<T>() * dba;
    const T dt(d.dt());
    const Vec3<T> g = gravity_w.cast<T>();
    const Mat3<T> R1t = R1.transpose();
    Eigen::Matrix<T, 9, 1> r;
    r.template segment<3>(0) = log_so3<T>((dR.transpose() * R1t * R2).eval());
    r.template segment<3>(3) = R1t * (vel2 - vel1 - g * dt) - dv;
    r.template segment<3>(6) = R1t * (p2 - p1 - vel1 * dt - T(0.5) * g * dt * dt) - dp;
    Eigen::Map<Eigen::Matrix<T, 9, 1>> weighted(out);
    weighted = weight.cast<T>() * r;
    return true;
  }
};

struct StatePrior {
  Eigen::Quaterniond q_mean;
  Eigen::Vector3d t_mean, v_mean;
  Eigen::Matrix<double, 9, 9> weight;

  template <typename T>
  bool operator()(const T* q_c_w, const T* t_c_w, const T* v_w, T* out) const {
    const Eigen::Map<const Eigen::Quaternion<T>> q(q_c_w);
    // The left increment that takes the mean to q (EigenQuaternionManifold's Plus is q(delta) * q).
    const Eigen::Quaternion<T> d = q * q_mean.conjugate().cast<T>();
    const T dq[4] = {d.w(), d.x(), d.y(), d.z()};
    Eigen::Matrix<T, 9, 1> r;
    ceres::QuaternionToAngleAxis(dq, r.data());
    r.template segment<3>(3) = Eigen::Map<const Vec3<T>>(t_c_w) - t_mean.cast<T>();
    r.template segment<3>(6) = Eigen::Map<const Vec3<T>>(v_w) - v_mean.cast<T>();
    Eigen::Map<Eigen::Matrix<T, 9, 1>> weighted(out);
    weighted = weight.cast<T>() * r;
    return true;
  }
};

}  // namespace

template <int N>
Eigen::Matrix<double, N, N> sqrt_information(const Eigen::Matrix<double, N, N>& covariance) {
  const Eigen::Matrix<double, N, N> symmetric = 0.5 * (covariance + covariance.transpose());
  const Eigen::LLT<Eigen::Matrix<double, N, N>> llt(symmetric);
  ORBATLAS_CHECK(llt.info() == Eigen::Success && covariance.allFinite(),
                 "sqrt_information: the covariance is not positive definite");
  // covariance = C C^T, information = C^-T C^-1, so its square root is C^-1.
  const Eigen::Matrix<double, N, N> C = llt.matrixL();
  return C.inverse();
}
template Eigen::Matrix<double, 9, 9> sqrt_information<9>(const Eigen::Matrix<double, 9, 9>&);

std::unique_ptr<ceres::CostFunction> make_inertial_cost(std::shared_ptr<const Preintegration> increments,
                                                        const Pose3& T_c_i, const Eigen::Vector3d& gravity_w) {
  ORBATLAS_CHECK(increments && increments->dt() > 0.0, "an inertial cost needs increments over some time");
  auto* f = new InertialResidual{};
  f->weight = sqrt_information<9>(increments->covariance());
  f->increments = std::move(increments);
  f->R_c_i = T_c_i.q.normalized().toRotationMatrix();
  f->t_c_i = T_c_i.t;
  f->gravity_w = gravity_w;
  return std::make_unique<ceres::AutoDiffCostFunction<InertialResidual, 9, 4, 3, 3, 4, 3, 3, 6>>(f);
}

std::unique_ptr<ceres::CostFunction> make_state_prior(const Pose3& T_c_w, const Eigen::Vector3d& v_w,
                                                      const StateCovariance& covariance) {
  auto* f = new StatePrior{};
  f->q_mean = T_c_w.q.normalized();
  f->t_mean = T_c_w.t;
  f->v_mean = v_w;
  f->weight = sqrt_information<9>(covariance);
  return std::make_unique<ceres::AutoDiffCostFunction<StatePrior, 9, 4, 3, 3>>(f);
}

std::unique_ptr<ceres::CostFunction> make_diagonal_prior(const Eigen::VectorXd& mean, const Eigen::VectorXd& sigma) {
  ORBATLAS_CHECK(mean.size() == sigma.size() && mean.size() > 0, "a diagonal prior needs one sigma per value");
  ORBATLAS_CHECK((sigma.array() > 0.0).all() && sigma.allFinite(), "a diagonal prior's sigmas must be > 0");
  const ceres::Matrix A = sigma.cwiseInverse().asDiagonal();
  return std::make_unique<ceres::NormalPrior>(A, mean);
}

}  // namespace orbatlas
