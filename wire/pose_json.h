#pragma once
// Poses in API replies: {"t": [x, y, z], "q": [qx, qy, qz, qw]} (metres; the
// rotation of the body in the map frame, Hamilton, as in TUM files).
#include <nlohmann/json.hpp>

#include "core/geometry/pose.h"

namespace orbatlas {

nlohmann::json pose_to_json(const Pose3& pose);
Pose3 pose_from_json(const nlohmann::json& j);  // throws nlohmann::json::exception / Error

}  // namespace orbatlas
