#include "core/optimization/inertial_cost.h"

#include <ceres/autodiff_cost_function.h>
#include <ceres/normal_prior.h>
#include <ceres/sized_cost_function.h>

#include <Eigen/Geometry>
#include <cmath>

#include "core/common/error.h"
#include "core/imu/inertial_residual.h"

namespace orbatlas {
namespace {

// The IMU's pose in the world from the camera pose T_c_w: T_w_i = T_c_w^-1 * T_c_i.
template <typename T>
void imu_pose(const T* q_c_w, const T* t_c_w, const Eigen::Matrix3d& R_c_i, const Eigen::Vector3d& t_c_i,
              Mat3T<T>& R_w_i, Vec3T<T>& p_w_i) {
  const Eigen::Map<const Eigen::Quaternion<T>> q(q_c_w);
  const Eigen::Map<const Vec3T<T>> t(t_c_w);
  const Mat3T<T> R_w_c = q.conjugate().toRotationMatrix();
  R_w_i = R_w_c * R_c_i.cast<T>();
  p_w_i = R_w_c * (t_c_i.cast<T>() - t);
}

struct InertialResidual {
  std::shared_ptr<const Preintegration> increments;
  Eigen::Matrix3d R_c_i;
  Eigen::Vector3d t_c_i, gravity_w;
  Eigen::Matrix<double, 9, 9> weight;  // square root of the information

  // scale: the scale correction (gyro, accel), or null for none.
  template <typename T>
  void evaluate(const T* q1, const T* t1, const T* v1, const T* q2, const T* t2, const T* v2, const T* bias,
                const T* scale, T* out) const {
    Mat3T<T> R1, R2;
    Vec3T<T> p1, p2;
    imu_pose(q1, t1, R_c_i, t_c_i, R1, p1);
    imu_pose(q2, t2, R_c_i, t_c_i, R2, p2);
    const auto vec = [](const T* x) { return x ? Vec3T<T>(x[0], x[1], x[2]) : Vec3T<T>(Vec3T<T>::Zero()); };
    Eigen::Map<Eigen::Matrix<T, 9, 1>> weighted(out);
    weighted =
        weight.cast<T>() * inertial_residual<T>(*increments, R1, p1, vec(v1), R2, p2, vec(v2), vec(bias), vec(bias + 3),
                                                gravity_w.cast<T>(), vec(scale), vec(scale ? scale + 3 : nullptr));
  }

  template <typename T>
  bool operator()(const T* q1, const T* t1, const T* v1, const T* q2, const T* t2, const T* v2, const T* bias,
                  T* out) const {
    evaluate<T>(q1, t1, v1, q2, t2, v2, bias, nullptr, out);
    return true;
  }
};

struct ScaledInertialResidual : InertialResidual {
  template <typename T>
  bool operator()(const T* q1, const T* t1, const T* v1, const T* q2, const T* t2, const T* v2, const T* bias,
                  const T* scale, T* out) const {
    evaluate<T>(q1, t1, v1, q2, t2, v2, bias, scale, out);
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
    r.template segment<3>(3) = Eigen::Map<const Vec3T<T>>(t_c_w) - t_mean.cast<T>();
    r.template segment<3>(6) = Eigen::Map<const Vec3T<T>>(v_w) - v_mean.cast<T>();
    Eigen::Map<Eigen::Matrix<T, 9, 1>> weighted(out);
    weighted = weight.cast<T>() * r;
    return true;
  }
};

// Linear: the Jacobians are -W and W.
class BiasWalkCost final : public ceres::SizedCostFunction<6, 6, 6> {
 public:
  explicit BiasWalkCost(const Eigen::Matrix<double, 6, 1>& weight) : weight_(weight) {}
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    for (int i = 0; i < 6; ++i) residuals[i] = weight_[i] * (parameters[1][i] - parameters[0][i]);
    for (int b = 0; b < 2; ++b) {
      if (!jacobians || !jacobians[b]) continue;
      Eigen::Map<Eigen::Matrix<double, 6, 6, Eigen::RowMajor>> J(jacobians[b]);
      J.setZero();
      J.diagonal() = b == 0 ? Eigen::Matrix<double, 6, 1>(-weight_) : weight_;
    }
    return true;
  }

 private:
  Eigen::Matrix<double, 6, 1> weight_;
};

template <typename Residual>
std::unique_ptr<Residual> inertial_residual_of(std::shared_ptr<const Preintegration> increments, const Pose3& T_c_i,
                                               const Eigen::Vector3d& gravity_w) {
  ORBATLAS_CHECK(increments && increments->dt() > 0.0, "an inertial cost needs increments over some time");
  auto f = std::make_unique<Residual>();
  f->weight = whitening<9>(increments->covariance());
  f->increments = std::move(increments);
  f->R_c_i = T_c_i.q.normalized().toRotationMatrix();
  f->t_c_i = T_c_i.t;
  f->gravity_w = gravity_w;
  return f;
}

}  // namespace

std::unique_ptr<ceres::CostFunction> make_bias_walk_cost(const ImuNoise& noise, double dt) {
  ORBATLAS_CHECK(std::isfinite(dt) && dt > 0.0, "a bias walk cost needs dt > 0, not " << dt);
  const double gyro = std::sqrt(noise.gyro_walk_variance(dt)), accel = std::sqrt(noise.accel_walk_variance(dt));
  ORBATLAS_CHECK(gyro > 0.0 && accel > 0.0, "a bias walk cost needs random walk densities > 0");
  Eigen::Matrix<double, 6, 1> weight;
  weight << Eigen::Vector3d::Constant(1.0 / gyro), Eigen::Vector3d::Constant(1.0 / accel);
  return std::make_unique<BiasWalkCost>(weight);
}

std::unique_ptr<ceres::CostFunction> make_inertial_cost(std::shared_ptr<const Preintegration> increments,
                                                        const Pose3& T_c_i, const Eigen::Vector3d& gravity_w) {
  return std::make_unique<ceres::AutoDiffCostFunction<InertialResidual, 9, 4, 3, 3, 4, 3, 3, 6>>(
      inertial_residual_of<InertialResidual>(std::move(increments), T_c_i, gravity_w).release());  // owns it
}

std::unique_ptr<ceres::CostFunction> make_scaled_inertial_cost(std::shared_ptr<const Preintegration> increments,
                                                               const Pose3& T_c_i, const Eigen::Vector3d& gravity_w) {
  return std::make_unique<ceres::AutoDiffCostFunction<ScaledInertialResidual, 9, 4, 3, 3, 4, 3, 3, 6, 6>>(
      inertial_residual_of<ScaledInertialResidual>(std::move(increments), T_c_i, gravity_w).release());  // owns it
}

std::unique_ptr<ceres::CostFunction> make_state_prior(const Pose3& T_c_w, const Eigen::Vector3d& v_w,
                                                      const StateCovariance& covariance) {
  auto f = std::make_unique<StatePrior>();
  f->q_mean = T_c_w.q.normalized();
  f->t_mean = T_c_w.t;
  f->v_mean = v_w;
  f->weight = whitening<9>(covariance);
  return std::make_unique<ceres::AutoDiffCostFunction<StatePrior, 9, 4, 3, 3>>(f.release());  // owns it
}

std::unique_ptr<ceres::CostFunction> make_diagonal_prior(const Eigen::VectorXd& mean, const Eigen::VectorXd& sigma) {
  ORBATLAS_CHECK(mean.size() == sigma.size() && mean.size() > 0, "a diagonal prior needs one sigma per value");
  ORBATLAS_CHECK((sigma.array() > 0.0).all() && sigma.allFinite(), "a diagonal prior's sigmas must be > 0");
  const ceres::Matrix A = sigma.cwiseInverse().asDiagonal();
  return std::make_unique<ceres::NormalPrior>(A, mean);
}

}  // namespace orbatlas
