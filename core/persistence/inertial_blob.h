#pragma once
// The blob of a keyframe's inertial link (keyframe_inertial_links.increments,
// docs/schema.md): the measurements of a Preintegration with its bias and noise,
// so that loading integrates them again into the very same increments,
// covariance and Jacobians.
#include <string>
#include <string_view>

#include "core/imu/preintegration.h"

namespace orbatlas {

inline constexpr double kIncrementsBlobVersion = 2.0;  // 1: without the vibration's variances (read as zero)

std::string encode_increments(const Preintegration& increments);
// Throws DataError naming `what` for an unknown version, a size that is not
// 17 (version 1: 11) + 7 per measurement, a value that is not finite, a dt or
// density <= 0, a vibration variance < 0.
Preintegration decode_increments(std::string_view blob, const std::string& what);

}  // namespace orbatlas
