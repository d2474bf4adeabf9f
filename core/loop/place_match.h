#pragma once
// A recognised place: a keyframe of the active map (`current`) seen again in a
// local window around a matched keyframe, with the rigid transform that aligns
// the two (stereo maps have metric scale: SE3). Same map: a loop; another map:
// a merge.
#include <memory>
#include <vector>

#include "core/geometry/pose.h"
#include "core/map/keyframe.h"

namespace orbatlas {

struct PlaceMatch {
  std::shared_ptr<KeyFrame> current;      // the keyframe the place was verified on (latest)
  std::shared_ptr<KeyFrame> matched;      // the window keyframe the transform refers to (K_m)
  std::shared_ptr<KeyFrame> detected_on;  // the keyframe the bag of words fired on (K_a)
  // Camera pose of `current` in the matched keyframe's world, i.e. where the
  // window says the current camera is: T_c_w corrected = T_cur_m * T_m_w.
  Pose3 T_c_w_corrected;
  Pose3 T_cur_m;                                  // camera of `current` <- camera of `matched`
  std::vector<std::shared_ptr<KeyFrame>> window;  // matched and its best covisibles
  std::vector<std::shared_ptr<MapPoint>> window_points;
  int matches = 0;             // current keypoints associated with window points (final pass)
  int verified_keyframes = 0;  // keyframes that confirmed the transform (incl. detected_on)
  bool same_map() const { return current && matched && current->map_id() == matched->map_id(); }
};

}  // namespace orbatlas
