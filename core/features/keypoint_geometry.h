#pragma once
// What the camera model says about detected keypoints: the unit bearing of each
// (distortion removed) and its position in the ideal pinhole image.
#include <vector>

#include "core/camera/camera.h"
#include "core/features/keypoint.h"

namespace orbatlas {

// Fills bearing = camera.unproject(uv) and uv_undistorted = (fx x/z + cx,
// fy y/z + cy) with the camera's fx, fy, cx, cy. A fisheye bearing at or beyond
// 90 degrees (z <= 0) has no pinhole pixel: uv_undistorted is then NaN.
void compute_keypoint_geometry(const Camera& camera, std::vector<Keypoint>& keypoints);

}  // namespace orbatlas
