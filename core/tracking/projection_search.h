#pragma once
// Matching map points to a frame's keypoints by projecting them with a predicted
// pose (ORB-SLAM's SearchByProjection, both flavours) and by the bag of words
// against a keyframe (SearchByBoW). All assign frame.map_points; they never
// overwrite a keypoint that already has a point.
#include <Eigen/Core>
#include <memory>
#include <vector>

#include "core/camera/camera.h"
#include "core/geometry/pose.h"
#include "core/map/keyframe.h"
#include "core/map/scale_pyramid.h"
#include "core/tracking/frame.h"
#include "core/tracking/frame_camera.h"

namespace orbatlas {

// A map point predicted in the frame (ORB-SLAM's isInFrustum result).
struct ProjectedPoint {
  std::shared_ptr<MapPoint> point;
  Eigen::Vector2f uv;
  float u_right = -1.0f;  // predicted right-image column, -1 without stereo
  int level = 0;          // predicted pyramid level
  float view_cos = 1.0f;  // cosine between the viewing ray and the point's mean normal
};

// Frustum test: in front of the camera, inside the image, within the point's
// distance range (with ORB-SLAM's 0.8 / 1.2 margins) and seen within 60 degrees
// of its mean viewing direction.
bool project_into_frame(const MapPoint& point, const Pose3& T_c_w, const FrameCamera& cam, ProjectedPoint* out);

// Local-map search: each predicted point against the keypoints around its
// prediction (radius th * (2.5 if seen head-on else 4) * scale^level, levels
// level-1..level). Returns the number of new associations.
int search_projected_points(Frame& frame, const std::vector<ProjectedPoint>& points, const FrameCamera& cam, float th,
                            float ratio = 0.8f);

// Motion-model search: the last frame's associated points (outliers excluded)
// projected with the predicted pose T_c_w, radius th * scale^level around the
// prediction, with a rotation-consistency check. Returns the number of matches.
int search_from_last_frame(Frame& current, const Frame& last, const Pose3& T_c_w, const FrameCamera& cam, float th);

// Bag-of-words search: the keyframe's map points against the frame's keypoints
// under the same vocabulary node (frame.feature_vector must be filled). Ratio
// test and rotation check. Returns the number of matches.
int search_by_bow(const KeyFrame& keyframe, Frame& frame, float ratio = 0.7f);

}  // namespace orbatlas
