#pragma once
// 95% quantiles of the chi-square distribution used to classify reprojection
// errors (ORB-SLAM's thresholds): 2 degrees of freedom for a monocular
// observation (u, v), 3 for a rectified stereo one (u, v, u_right); 9 for the
// preintegrated IMU between two keyframes (rotation, velocity, position).
namespace orbatlas {

inline constexpr double kChi2Mono95 = 5.991;
inline constexpr double kChi2Stereo95 = 7.815;
inline constexpr double kChi2Inertial95 = 16.919;

}  // namespace orbatlas
