#include "core/tracking/frame_camera.h"

namespace orbatlas {

double FrameCamera::baseline() const {
  if (!camera || bf <= 0.0) return 0.0;
  return bf / camera->calibration().fx;
}

}  // namespace orbatlas
