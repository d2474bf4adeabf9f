#pragma once
// What the atlas database records about a session (a recording or a client
// connection): its sensor and the calibration of its camera rig.
#include <cstdint>
#include <string>
#include <vector>

#include "core/camera/camera_calibration.h"
#include "core/common/ids.h"
#include "core/common/timestamp.h"
#include "core/io/settings.h"

namespace orbatlas {

struct SessionInfo {
  SessionId id = 0;  // chosen by the caller; unique in the database
  std::string name;
  SensorType sensor = SensorType::kStereo;
  TimestampNs created_ns = 0;              // Unix time
  std::vector<CameraCalibration> cameras;  // the rig: index 0 left, 1 right
};

}  // namespace orbatlas
