#include "core/optimization/reprojection_residuals.h"

#include <array>
#include <cmath>
#include <variant>

#include "core/camera/kannala_brandt.h"
#include "core/camera/pinhole_radtan.h"
#include "core/common/error.h"
#include "core/optimization/chained_costs.h"

namespace orbatlas {
namespace {

template <class Residual>
std::unique_ptr<ceres::CostFunction> pose_only(const Residual& residual, const Eigen::Vector3d& p_w) {
  return std::make_unique<PoseOnlyChainCost<Residual>>(residual, p_w);
}

template <class Residual>
std::unique_ptr<ceres::CostFunction> pose_point(const Residual& residual) {
  return std::make_unique<PosePointChainCost<Residual>>(residual);
}

template <class CameraT, class Make>
std::unique_ptr<ceres::CostFunction> with_residual(const CameraT& camera, const PixelObservation& obs, double bf,
                                                   bool pad_mono, const Make& make) {
  ORBATLAS_CHECK(obs.level_sigma2 > 0.0 && std::isfinite(obs.level_sigma2),
                 "reprojection residual: level sigma2 must be positive, got " << obs.level_sigma2);
  const double inv_sigma = 1.0 / std::sqrt(obs.level_sigma2);
  if (obs.u_right) {
    ORBATLAS_CHECK(bf > 0.0, "reprojection residual: a stereo observation needs bf > 0, got " << bf);
    return make(StereoResidual<CameraT>{&camera, obs.uv, *obs.u_right, bf, inv_sigma});
  }
  if (pad_mono) return make(MonoResidual<CameraT, 3>{&camera, obs.uv, inv_sigma});
  return make(MonoResidual<CameraT>{&camera, obs.uv, inv_sigma});
}

template <class Make>
std::unique_ptr<ceres::CostFunction> dispatch(const Camera& camera, const PixelObservation& obs, double bf,
                                              bool pad_mono, const Make& make) {
  switch (camera.model()) {
    case CameraModel::kPinholeRadTan:
      return with_residual(dynamic_cast<const PinholeRadTan&>(camera), obs, bf, pad_mono, make);
    case CameraModel::kKannalaBrandt:
      return with_residual(dynamic_cast<const KannalaBrandt&>(camera), obs, bf, pad_mono, make);
  }
  throw_error("reprojection residual: unsupported camera model");
}

}  // namespace

std::unique_ptr<ceres::CostFunction> make_pose_only_cost(const Camera& camera, const Eigen::Vector3d& p_w,
                                                         const PixelObservation& obs, double bf) {
  return dispatch(camera, obs, bf, false, [&](const auto& residual) { return pose_only(residual, p_w); });
}

struct PoseOnlyCosts::Slot {
  // Built in place (a ceres::CostFunction cannot be moved or copied); empty
  // until add() fills it. Every residual with_residual can make is here, the
  // padded ones too (add() never asks for them, but the dispatch is compiled for each).
  std::variant<std::monostate, PoseOnlyChainCost<StereoResidual<PinholeRadTan>>,
               PoseOnlyChainCost<MonoResidual<PinholeRadTan>>, PoseOnlyChainCost<MonoResidual<PinholeRadTan, 3>>,
               PoseOnlyChainCost<StereoResidual<KannalaBrandt>>, PoseOnlyChainCost<MonoResidual<KannalaBrandt>>,
               PoseOnlyChainCost<MonoResidual<KannalaBrandt, 3>>>
      cost;
};

PoseOnlyCosts::PoseOnlyCosts(std::size_t capacity) : slots_(std::make_unique<Slot[]>(capacity)), capacity_(capacity) {
  costs_.reserve(capacity);
}

PoseOnlyCosts::~PoseOnlyCosts() = default;

void PoseOnlyCosts::add(const Camera& camera, const Eigen::Vector3d& p_w, const PixelObservation& obs, double bf) {
  ORBATLAS_CHECK(costs_.size() < capacity_, "pose-only costs: more than the " << capacity_ << " made room for");
  Slot& slot = slots_[costs_.size()];
  // The same residual as make_pose_only_cost (dispatch and with_residual), built in the slot.
  dispatch(camera, obs, bf, false, [&](const auto& residual) -> std::unique_ptr<ceres::CostFunction> {
    costs_.push_back(&slot.cost.template emplace<PoseOnlyChainCost<std::decay_t<decltype(residual)>>>(residual, p_w));
    return nullptr;
  });
}

std::unique_ptr<ceres::CostFunction> make_pose_point_cost(const Camera& camera, const PixelObservation& obs, double bf,
                                                          bool pad_mono) {
  return dispatch(camera, obs, bf, pad_mono, [](const auto& residual) { return pose_point(residual); });
}

std::optional<double> residual_chi2(const ceres::CostFunction& cost, const double* const* parameters) {
  std::array<double, 3> r{};
  if (cost.num_residuals() > static_cast<int>(r.size())) return std::nullopt;
  if (!cost.Evaluate(parameters, r.data(), nullptr)) return std::nullopt;
  double chi2 = 0.0;
  for (int i = 0; i < cost.num_residuals(); ++i)
    chi2 += r[static_cast<std::size_t>(i)] * r[static_cast<std::size_t>(i)];
  return chi2;
}

}  // namespace orbatlas
