#include "core/eval/alignment.h"

#include <Eigen/SVD>

#include "core/common/error.h"

namespace orbatlas {

std::optional<AlignMode> parse_align_mode(std::string_view text) {
  if (text == "none") return AlignMode::kNone;
  if (text == "se3") return AlignMode::kSe3;
  if (text == "sim3") return AlignMode::kSim3;
  return std::nullopt;
}

const char* align_mode_name(AlignMode mode) {
  switch (mode) {
    case AlignMode::kNone:
      return "none";
    case AlignMode::kSe3:
      return "se3";
    case AlignMode::kSim3:
      return "sim3";
  }
  return "?";
}

Similarity3 align_positions(const std::vector<Eigen::Vector3d>& estimate,
                            const std::vector<Eigen::Vector3d>& ground_truth, AlignMode mode) {
  ORBATLAS_CHECK(estimate.size() == ground_truth.size(),
                 "align_positions: " << estimate.size() << " estimated vs " << ground_truth.size() << " true positions");
  ORBATLAS_CHECK(estimate.size() >= 3, "alignment needs at least 3 matched poses, got " << estimate.size());
  if (mode == AlignMode::kNone) return {};

  const double n = static_cast<double>(estimate.size());
  Eigen::Vector3d mean_e = Eigen::Vector3d::Zero(), mean_g = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < estimate.size(); ++i) {
    mean_e += estimate[i];
    mean_g += ground_truth[i];
  }
  mean_e /= n;
  mean_g /= n;

  Eigen::Matrix3d sigma = Eigen::Matrix3d::Zero();  // cross-covariance (gt x est)
  double var_e = 0.0;                               // variance of the estimate
  for (std::size_t i = 0; i < estimate.size(); ++i) {
    const Eigen::Vector3d e = estimate[i] - mean_e;
    sigma += (ground_truth[i] - mean_g) * e.transpose();
    var_e += e.squaredNorm();
  }
  sigma /= n;
  var_e /= n;

  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(sigma, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Vector3d s(1.0, 1.0, 1.0);
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0) s(2) = -1.0;  // no reflection
  const Eigen::Matrix3d r = svd.matrixU() * s.asDiagonal() * svd.matrixV().transpose();

  Similarity3 result;
  result.rotation = Eigen::Quaterniond(r).normalized();
  if (mode == AlignMode::kSim3) {
    ORBATLAS_CHECK(var_e > 0.0, "sim3 alignment: the estimated positions are all equal");
    result.scale = svd.singularValues().dot(s) / var_e;
    ORBATLAS_CHECK(result.scale > 0.0, "sim3 alignment: degenerate scale " << result.scale);
  }
  result.translation = mean_g - result.scale * (result.rotation * mean_e);
  return result;
}

}  // namespace orbatlas
