#pragma once
#include <memory>

#include "core/camera/camera.h"

namespace orbatlas {

// Builds the camera for a calibration; throws Error on invalid parameters
// (non-positive focal length or size, wrong number of distortion coefficients).
std::unique_ptr<Camera> make_camera(const CameraCalibration& calibration);

// The checks make_camera() applies, without building the camera: fx, fy > 0,
// width, height > 0, every parameter finite, 4 or 5 coefficients for
// kPinholeRadTan and 4 for kKannalaBrandt. Throws Error naming the problem.
void check_calibration(const CameraCalibration& calibration);

}  // namespace orbatlas
