#pragma once
// A detected feature: where it is in the (distorted) image and its pyramid level
// and orientation, plus what the camera model says about it.
#include <Eigen/Core>
#include <vector>

#include "core/features/descriptor.h"

namespace orbatlas {

struct Keypoint {
  Eigen::Vector2f uv = Eigen::Vector2f::Zero();  // detected position, level-0 pixels (distorted image)
  int level = 0;                                 // pyramid level it was detected on
  float angle_deg = 0.0f;                        // orientation (intensity centroid), degrees in [0, 360)
  float response = 0.0f;                         // FAST score
  // Filled from the camera model (features/keypoint_geometry.h):
  Eigen::Vector3d bearing = Eigen::Vector3d::UnitZ();        // unit ray in the camera frame
  Eigen::Vector2f uv_undistorted = Eigen::Vector2f::Zero();  // pinhole pixel with the camera's fx, fy, cx, cy
};

// A pixel of a pyramid level `ratio` times smaller than the full image (the full
// image's size over the level's, per axis), in the full image's pixels and back.
// Linear resizes map pixel centres onto each other, x_full = (x_level + 0.5) *
// ratio - 0.5, also through a chain of them.
inline float full_image_coordinate(float x_level, float ratio) { return (x_level + 0.5f) * ratio - 0.5f; }
inline float level_coordinate(float x_full, float ratio) { return (x_full + 0.5f) / ratio - 0.5f; }

// Keypoints and descriptors of one image, index-aligned.
struct ImageFeatures {
  std::vector<Keypoint> keypoints;
  std::vector<Descriptor> descriptors;
  int width = 0, height = 0;
};

}  // namespace orbatlas
