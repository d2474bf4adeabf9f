#pragma once
// 64-bit ids of the map model, unique in a whole atlas (see IdAllocator) and
// persisted. KeyframeId is the keyframe database's.
#include <cstdint>

#include "core/vocabulary/keyframe_database.h"

namespace orbatlas {

using MapPointId = std::uint64_t;
using MapId = std::uint64_t;

}  // namespace orbatlas
