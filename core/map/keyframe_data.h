#pragma once
// The immutable content of a keyframe, as tracking hands it over.
#include <cstdint>
#include <vector>

#include "core/features/feature_grid.h"
#include "core/features/keypoint.h"
#include "core/geometry/pose.h"
#include "core/vocabulary/bow_vector.h"

namespace orbatlas {

struct KeyFrameData {
  std::int64_t timestamp_ns = 0;
  Pose3 T_w_b;             // initial body pose in the map's world (mutable later)
  Pose3 T_b_c;             // (left) camera in the body, fixed
  ImageFeatures features;  // keypoints + descriptors; one map point slot per keypoint
  // Stereo: per keypoint, index-aligned with features.keypoints; -1 when unmatched.
  // Both empty for a monocular keyframe.
  std::vector<float> depth;
  std::vector<float> u_right;
  BowVector bow;
  FeatureVector feature_vector;
  FeatureGrid grid;  // over features.keypoints, for projection searches
};

}  // namespace orbatlas
