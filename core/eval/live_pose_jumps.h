#pragma once
// How far a device's live pose jumps when the map it is tracked in is corrected
// (a loop closure, a merge, a global BA's result or an inertial initialisation
// applied: Atlas::maps_edits counts them). At the first tracked frame after a
// correction, the jump is the distance between its position and the one the
// frames before predicted (constant velocity from the last two; the last one
// alone after a single frame): what a robot steering by the replies sees move.
// The map's frame may change with a merge: the positions are those the device
// was given, in whatever map each was. An untracked frame starts afresh.
#include <cstdint>
#include <optional>

#include <Eigen/Core>

#include "core/common/ids.h"

namespace orbatlas {

class LivePoseJumps {
 public:
  // One tracked frame: its position, the map it is in and the atlas's edits
  // when it was tracked. The jump [m] when the maps were edited (or the map
  // changed) since the tracked frame before it; none otherwise.
  std::optional<double> add(const Eigen::Vector3d& p_w, MapId map, std::uint64_t maps_edits);
  // A frame without a pose: the next one has nothing to be compared with.
  void lost();

 private:
  std::optional<Eigen::Vector3d> last_, before_last_;
  MapId map_ = 0;
  std::uint64_t edits_ = 0;
};

}  // namespace orbatlas
