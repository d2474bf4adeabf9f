#include "core/eval/alignment.h"

#include <Eigen/Geometry>
#include <cmath>

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
  ORBATLAS_CHECK(estimate.size() == ground_truth.size(), "align_positions: " << estimate.size() << " estimated vs "
                                                                             << ground_truth.size()
                                                                             << " true positions");
  ORBATLAS_CHECK(estimate.size() >= 3, "alignment needs at least 3 matched poses, got " << estimate.size());
  if (mode == AlignMode::kNone) return {};

  // Eigen's Umeyama (columns are points): the rotation without reflection, and
  // the scale with kSim3; the 4x4 result is [c R, t; 0 1].
  Eigen::Matrix3Xd src(3, estimate.size()), dst(3, ground_truth.size());
  for (std::size_t i = 0; i < estimate.size(); ++i) {
    src.col(static_cast<Eigen::Index>(i)) = estimate[i];
    dst.col(static_cast<Eigen::Index>(i)) = ground_truth[i];
  }
  const bool with_scale = mode == AlignMode::kSim3;
  if (with_scale) {
    const double spread = (src.colwise() - src.rowwise().mean()).squaredNorm();
    ORBATLAS_CHECK(spread > 0.0, "sim3 alignment: the estimated positions are all equal");
  }
  const Eigen::Matrix4d T = Eigen::umeyama(src, dst, with_scale);
  Similarity3 result;
  const Eigen::Matrix3d scaled_rotation = T.topLeftCorner<3, 3>();
  result.scale = with_scale ? scaled_rotation.col(0).norm() : 1.0;
  ORBATLAS_CHECK(std::isfinite(result.scale) && result.scale > 0.0,
                 "sim3 alignment: degenerate scale " << result.scale);
  result.rotation = Eigen::Quaterniond(scaled_rotation / result.scale).normalized();
  result.translation = T.topRightCorner<3, 1>();
  return result;
}

}  // namespace orbatlas
