#pragma once
// The camera tracking and mapping work with: the model the keypoints are in
// (the rectified left pinhole for a stereo rig), the stereo constant and the
// scale pyramid of the features.
#include "core/camera/camera.h"
#include "core/map/scale_pyramid.h"

namespace orbatlas {

struct FrameCamera {
  const Camera* camera = nullptr;  // not owned
  double bf = 0.0;                 // baseline * fx; 0 for monocular
  ScalePyramid pyramid;

  double baseline() const;  // bf / fx (0 for monocular)
};

}  // namespace orbatlas
