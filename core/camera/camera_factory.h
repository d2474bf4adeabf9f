#pragma once
#include <memory>

#include "core/camera/camera.h"

namespace orbatlas {

// Builds the camera for a calibration; throws Error on invalid parameters
// (non-positive focal length or size, wrong number of distortion coefficients).
std::unique_ptr<Camera> make_camera(const CameraCalibration& calibration);

}  // namespace orbatlas
