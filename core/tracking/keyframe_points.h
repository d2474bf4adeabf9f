#pragma once
// Filling a new keyframe with map points (ORB-SLAM's CreateNewKeyFrame): the
// frame's tracked points, then new points from its closest stereo matches.
//
// The keyframe is in its map from the start and becomes visible to local
// mapping through the observer lists of the first points it gets, so local
// mapping (fusing points into neighbours, culling points) may edit its slots
// while it is being filled. Every decision here is therefore taken from what
// the keyframe's slot holds at that moment, and every edit is one atomic step
// (KeyFrame::try_add_observation) whose loss is handled, never assumed away.
#include <cstddef>
#include <memory>

#include "core/geometry/pose.h"
#include "core/map/map.h"
#include "core/map/scale_pyramid.h"
#include "core/tracking/frame.h"

namespace orbatlas {

struct KeyframePointsOptions {
  double th_depth_m = 3.5;         // close stereo points (ORB-SLAM's ThDepth * baseline)
  bool all_stereo_points = false;  // a map's first keyframe: every stereo match
  int min_points = 100;            // keep adding the closest matches until this many

  // Throws Error naming the first value out of range.
  void check() const;
};

struct KeyframePointsResult {
  std::size_t observations = 0;  // tracked points the keyframe observes
  std::size_t created = 0;       // new map points
  std::size_t lost_races = 0;    // slots another thread filled first (their point is used)
};

// Adds the observations of the frame's tracked inliers to `keyframe`, then new
// map points from the stereo matches by increasing depth (all of them with
// `all_stereo_points`, otherwise those closer than th_depth_m and at least
// min_points in total). The frame's map_points are updated to what the
// keyframe holds (a slot fused meanwhile gives its new point).
KeyframePointsResult add_keyframe_points(Map& map, const std::shared_ptr<KeyFrame>& keyframe, Frame& frame,
                                         const Pose3& T_b_c, const ScalePyramid& pyramid,
                                         const KeyframePointsOptions& options);

}  // namespace orbatlas
