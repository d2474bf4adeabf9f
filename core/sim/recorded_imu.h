#pragma once
// The real EuRoC IMU recordings the repository ships (data/euroc/imu): the
// MH_05 flight's, and MH_01's from a lossy copy.
#include <filesystem>
#include <string>
#include <vector>

#include "core/common/timestamp.h"
#include "core/io/euroc_types.h"

namespace orbatlas::sim {

// The recording of a sequence; empty for a sequence without one.
std::filesystem::path recorded_imu_path(const std::string& sequence);

// Its samples stamped (after shifting by `offset`) in [first, last]. Throws
// DataError for a line that is not 7 numbers.
std::vector<ImuSample> load_recorded_imu(const std::string& sequence, TimestampNs first, TimestampNs last,
                                         TimestampNs offset = 0);

}  // namespace orbatlas::sim
