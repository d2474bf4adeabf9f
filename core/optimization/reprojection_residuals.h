#pragma once
// Reprojection residuals for any camera model, as Ceres cost functions
// (differentiated automatically through the camera model).
//
// Monocular (2): (u, v)_observed - project(p_c), through the model's templated
// Camera::project_t, so distortion and fisheye models differentiate exactly.
// Rectified stereo (3): adds u_right_observed - (u - bf / z) (ORB-SLAM's stereo
// edge; exact when the camera is the rectified, distortion-free pinhole).
// Both are scaled by 1 / sigma with sigma^2 = the keypoint level's sigma2, so the
// squared norm of the residual is the chi2 of the observation.
//
// The factories dispatch on Camera::model() to a functor templated on the
// concrete model. The cost function keeps a pointer to the camera: the camera
// must outlive it.
#include <ceres/cost_function.h>

#include <Eigen/Core>
#include <memory>
#include <optional>
#include <vector>

#include "core/camera/camera.h"
#include "core/optimization/pose_parameters.h"

namespace orbatlas {

// One keypoint observation of a point.
struct PixelObservation {
  Eigen::Vector2d uv = Eigen::Vector2d::Zero();  // observed pixel (the camera model's image)
  std::optional<double> u_right;                 // rectified stereo: column in the right image
  double level_sigma2 = 1.0;                     // sigma^2 of the keypoint's pyramid level
};

// kRows = 3 pads a third, constant zero residual, so that a problem mixing
// monocular and stereo observations has rows of one size (Ceres then uses its
// fixed-size Schur eliminator); the value and the chi2 are unchanged.
template <class CameraT, int kRows = 2>
struct MonoResidual {
  static_assert(kRows == 2 || kRows == 3);
  static constexpr int kResiduals = kRows;
  const CameraT* camera = nullptr;  // not owned
  Eigen::Vector2d uv;
  double inv_sigma = 1.0;

  template <typename T>
  bool operator()(const T* p_c, T* r) const {
    T proj[2];
    if (!camera->project_t(p_c, proj)) return false;
    r[0] = (T(uv.x()) - proj[0]) * inv_sigma;
    r[1] = (T(uv.y()) - proj[1]) * inv_sigma;
    if constexpr (kRows == 3) r[2] = T(0.0);
    return true;
  }
};

template <class CameraT>
struct StereoResidual {
  static constexpr int kResiduals = 3;
  const CameraT* camera = nullptr;  // not owned
  Eigen::Vector2d uv;
  double u_right = 0.0;
  double bf = 0.0;  // baseline * fx of the rectified pair
  double inv_sigma = 1.0;

  template <typename T>
  bool operator()(const T* p_c, T* r) const {
    if (!(p_c[2] > T(0.0))) return false;
    T proj[2];
    if (!camera->project_t(p_c, proj)) return false;
    r[0] = (T(uv.x()) - proj[0]) * inv_sigma;
    r[1] = (T(uv.y()) - proj[1]) * inv_sigma;
    r[2] = (T(u_right) - (proj[0] - bf / p_c[2])) * inv_sigma;
    return true;
  }
};

// Parameter blocks (q_c_w[4], t_c_w[3]); the world point is a constant.
// (Reference autodiff form of PoseOnlyChainCost.)
template <class Residual>
struct PoseOnlyCost {
  Residual residual;
  Eigen::Vector3d p_w;

  template <typename T>
  bool operator()(const T* q, const T* t, T* r) const {
    const T p[3] = {T(p_w.x()), T(p_w.y()), T(p_w.z())};
    T p_c[3];
    world_to_camera(q, t, p, p_c);
    return residual(p_c, r);
  }
};

// Parameter blocks (q_c_w[4], t_c_w[3], p_w[3]). (Reference autodiff form of
// PosePointChainCost.)
template <class Residual>
struct PosePointCost {
  Residual residual;

  template <typename T>
  bool operator()(const T* q, const T* t, const T* p_w, T* r) const {
    T p_c[3];
    world_to_camera(q, t, p_w, p_c);
    return residual(p_c, r);
  }
};

// Stereo when obs.u_right is set (then bf must be > 0). Throws Error on a
// non-positive sigma2 or an unknown camera model. The costs are the chained
// forms of PoseOnlyCost / PosePointCost (chained_costs.h): same values and
// derivatives as autodiff over the whole functor, several times cheaper.
std::unique_ptr<ceres::CostFunction> make_pose_only_cost(const Camera& camera, const Eigen::Vector3d& p_w,
                                                         const PixelObservation& obs, double bf);
// The pose-only costs of one optimisation (make_pose_only_cost's), held in one
// array sized once: tracking optimises a frame's pose twice with hundreds of
// observations each, and a heap object per observation was 0.8 % of a
// stereo run's samples, with the allocator's share on top (perf, 2026-11-28).
class PoseOnlyCosts {
 public:
  explicit PoseOnlyCosts(std::size_t capacity);  // add() at most this many
  ~PoseOnlyCosts();
  PoseOnlyCosts(const PoseOnlyCosts&) = delete;
  PoseOnlyCosts& operator=(const PoseOnlyCosts&) = delete;

  // As make_pose_only_cost (the same checks and errors); Error past the capacity.
  void add(const Camera& camera, const Eigen::Vector3d& p_w, const PixelObservation& obs, double bf);
  const ceres::CostFunction& operator[](std::size_t i) const { return *costs_[i]; }
  ceres::CostFunction& operator[](std::size_t i) { return *costs_[i]; }  // ceres::Problem takes non-const
  std::size_t size() const { return costs_.size(); }

 private:
  struct Slot;  // one cost, of any of the concrete types
  std::unique_ptr<Slot[]> slots_;
  std::vector<ceres::CostFunction*> costs_;
  std::size_t capacity_ = 0;
};

// pad_mono: a monocular observation gets 3 rows (see MonoResidual).
std::unique_ptr<ceres::CostFunction> make_pose_point_cost(const Camera& camera, const PixelObservation& obs, double bf,
                                                          bool pad_mono = false);

// Squared norm of the (weighted) residual at `parameters`; nullopt when the point
// cannot be projected there (behind the camera, outside the model's domain).
std::optional<double> residual_chi2(const ceres::CostFunction& cost, const double* const* parameters);

}  // namespace orbatlas
