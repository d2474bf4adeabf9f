#pragma once
// One frame as tracking sees it (built by StereoFrontend from a stereo pair): features of the rectified left image,
// per-keypoint stereo depth, bearings, a search grid, and (filled by tracking)
// its pose and the map points its keypoints were associated with.
#include <memory>
#include <vector>

#include "core/common/timestamp.h"
#include "core/features/feature_grid.h"
#include "core/features/keypoint.h"
#include "core/geometry/pose.h"
#include "core/vocabulary/bow_vector.h"

namespace orbatlas {

class MapPoint;

struct Frame {
  TimestampNs t_ns = 0;
  ImageFeatures features;      // rectified left image; uv_undistorted == uv (no distortion)
  std::vector<float> depth;    // metres per keypoint, -1 without a stereo match
  std::vector<float> u_right;  // right column per keypoint, -1 without a stereo match
  FeatureGrid grid;
  BowVector bow;  // filled on demand (relocalization, keyframes)
  FeatureVector feature_vector;

  // Tracking state.
  Pose3 T_w_b;
  bool has_pose = false;
  std::vector<std::shared_ptr<MapPoint>> map_points;  // per keypoint, null when unassociated
  std::vector<bool> outlier;                          // per keypoint, set by pose optimisation

  std::size_t size() const { return features.keypoints.size(); }
  std::size_t stereo_count() const;
};

}  // namespace orbatlas
