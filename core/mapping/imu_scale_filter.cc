#include "core/mapping/imu_scale_filter.h"

#include <cmath>

#include <Eigen/Cholesky>

#include "core/common/error.h"

namespace orbatlas {
namespace {

Eigen::Matrix<double, 6, 1> stacked(const ImuScaleCorrection& c) {
  Eigen::Matrix<double, 6, 1> x;
  x << c.gyro, c.accel;
  return x;
}

}  // namespace

void ImuScaleFilterOptions::check() const {
  ORBATLAS_CHECK(std::isfinite(prior_sigma) && prior_sigma > 0.0 && prior_sigma < 0.05,
                 "IMU scale filter: prior_sigma must be in (0, 0.05), not " << prior_sigma);
  ORBATLAS_CHECK(std::isfinite(overlap) && overlap >= 1.0, "IMU scale filter: overlap must be >= 1, not " << overlap);
  ORBATLAS_CHECK(std::isfinite(max_correction) && max_correction > 0.0 && max_correction < 0.1,
                 "IMU scale filter: max_correction must be in (0, 0.1), not " << max_correction);
}

ImuScaleFilter::ImuScaleFilter(ImuScaleFilterOptions options) : options_(options) { options_.check(); }

ImuScaleInformation ImuScaleFilter::information(MapId map) const {
  const auto it = information_.find(map);
  if (it != information_.end()) return it->second;
  return ImuScaleInformation::Identity() / (options_.prior_sigma * options_.prior_sigma);
}

ImuScaleCorrection ImuScaleFilter::add(MapId map, const ImuScaleCorrection& current, const ImuScaleCorrection& window,
                                       const ImuScaleInformation& window_information) {
  const Eigen::Matrix<double, 6, 1> x_map = stacked(current), x_window = stacked(window);
  if (!x_window.allFinite() || !window_information.allFinite()) return current;
  const ImuScaleInformation prior = information(map);
  const ImuScaleInformation added = window_information / options_.overlap;
  const ImuScaleInformation fused = prior + added;
  const Eigen::Matrix<double, 6, 1> x = fused.ldlt().solve(prior * x_map + added * x_window);
  if (!x.allFinite()) return current;
  information_[map] = fused;
  const double m = options_.max_correction;
  ImuScaleCorrection out;
  out.gyro = x.head<3>().cwiseMax(-m).cwiseMin(m);
  out.accel = x.tail<3>().cwiseMax(-m).cwiseMin(m);
  return out;
}

}  // namespace orbatlas
