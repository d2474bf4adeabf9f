#pragma once
// A recognised place: a keyframe of the active map (`current`) seen again in a
// local window around a matched keyframe, with the rigid transform that aligns
// the two: a similarity when the current map's scale is free (a monocular map
// not made metric by an IMU), else rigid (scale 1). Same map: a loop; another
// map: a merge.
#include <memory>
#include <vector>

#include "core/geometry/pose.h"
#include "core/geometry/sim3.h"
#include "core/geometry/sim3_correction.h"
#include "core/map/keyframe.h"

namespace orbatlas {

struct PlaceMatch {
  std::shared_ptr<KeyFrame> current;      // the keyframe the place was verified on (latest)
  std::shared_ptr<KeyFrame> matched;      // the window keyframe the transform refers to (K_m)
  std::shared_ptr<KeyFrame> detected_on;  // the keyframe the bag of words fired on (K_a)
  // The matched keyframe's world seen from the camera of `current` (in the
  // current map's units), i.e. where the window says the current camera is:
  // S_c_w_corrected = S_cur_m * T_m_w.
  Sim3 S_c_w_corrected;
  Sim3 S_cur_m;             // camera of `current` <- camera of `matched` (scale: current units per matched units)
  bool scale_free = false;  // the scale was estimated (else it is 1)
  std::vector<std::shared_ptr<KeyFrame>> window;  // matched and its best covisibles
  std::vector<std::shared_ptr<MapPoint>> window_points;
  int matches = 0;             // current keypoints associated with window points (final pass)
  int verified_keyframes = 0;  // keyframes that confirmed the transform (incl. detected_on)
  // The current camera's rigid pose in the matched keyframe's world (its units).
  Pose3 T_c_w_corrected() const { return rigid_pose_c_w(S_c_w_corrected); }
  bool same_map() const { return current && matched && current->map_id() == matched->map_id(); }
};

}  // namespace orbatlas
