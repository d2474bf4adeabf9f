#pragma once
// Feeding a recording's IMU to a session the way a device does: before each
// frame, the samples up to the frame's time and the first one past it (so the
// frame's time is covered). Used by `orbatlas run`, `orbatlas stream` and uploads.
#include <cstddef>
#include <vector>

#include "core/io/euroc_types.h"

namespace orbatlas {

// The next batch from `imu` (in time order) for a frame at `t_ns`; `next` is
// the first sample not yet taken. At the first call, samples older than
// `history_ns` before the frame are skipped (a window that starts late).
inline std::vector<ImuSample> take_imu_batch(const std::vector<ImuSample>& imu, std::size_t& next, TimestampNs t_ns,
                                             TimestampNs history_ns = 1'000'000'000) {
  if (next == 0)
    while (next < imu.size() && imu[next].t_ns < t_ns - history_ns) ++next;
  std::vector<ImuSample> batch;
  while (next < imu.size() && imu[next].t_ns <= t_ns) batch.push_back(imu[next++]);
  if (next < imu.size()) batch.push_back(imu[next++]);
  return batch;
}

}  // namespace orbatlas
