#pragma once
// The EuRoC sequences whose real ground truth and camera timestamps ship in
// data/euroc (Machine Hall MH_01..MH_05 share one world frame; V1_01 is a room).
#include <filesystem>
#include <string>
#include <vector>

#include "core/common/timestamp.h"
#include "core/geometry/trajectory.h"

namespace orbatlas::sim {

struct SequenceInfo {
  std::string name;                         // "MH_01"
  std::filesystem::path ground_truth;       // TUM, 200 Hz
  std::filesystem::path camera_timestamps;  // ns per line
  bool machine_hall = false;
};

// Accepts "MH_01", "MH01", "mh_01_easy", "V1_01"...; throws Error listing the known ones.
SequenceInfo find_sequence(const std::string& name);
std::vector<std::string> machine_hall_sequence_names();

Trajectory load_ground_truth(const SequenceInfo& sequence);
std::vector<TimestampNs> load_camera_timestamps(const SequenceInfo& sequence);

}  // namespace orbatlas::sim
