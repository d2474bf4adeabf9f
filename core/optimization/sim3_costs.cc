#include "core/optimization/sim3_costs.h"

#include "core/camera/kannala_brandt.h"
#include "core/camera/pinhole_radtan.h"
#include "core/common/error.h"
#include "core/optimization/reprojection_residuals.h"

namespace orbatlas {
namespace {

template <class CameraT>
std::unique_ptr<ceres::CostFunction> make_for(const CameraT& camera, const Eigen::Vector3d& p,
                                              const Eigen::Vector2d& uv, double inv_sigma, Sim3Projection direction) {
  return std::make_unique<Sim3ProjectionCost<MonoResidual<CameraT>>>(MonoResidual<CameraT>{&camera, uv, inv_sigma}, p,
                                                                     direction);
}

}  // namespace

std::unique_ptr<ceres::CostFunction> make_sim3_projection_cost(const Camera& camera, const Eigen::Vector3d& p,
                                                               const Eigen::Vector2d& uv, double level_sigma2,
                                                               Sim3Projection direction) {
  ORBATLAS_CHECK(level_sigma2 > 0.0 && std::isfinite(level_sigma2),
                 "Sim3 projection cost: level sigma2 must be positive, got " << level_sigma2);
  const double inv_sigma = 1.0 / std::sqrt(level_sigma2);
  switch (camera.model()) {
    case CameraModel::kPinholeRadTan:
      return make_for(dynamic_cast<const PinholeRadTan&>(camera), p, uv, inv_sigma, direction);
    case CameraModel::kKannalaBrandt:
      return make_for(dynamic_cast<const KannalaBrandt&>(camera), p, uv, inv_sigma, direction);
  }
  throw_error("Sim3 projection cost: unsupported camera model");
}

}  // namespace orbatlas
