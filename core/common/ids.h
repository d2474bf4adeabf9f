#pragma once
// Every id type of the project, in one place. All are 64-bit and persisted:
// keyframes, map points and maps are unique in a whole atlas (handed out by
// core/map/id_allocator.h), sessions and upload jobs in a server's database. Each
// has an invalid value that is never handed out (the allocators stop before it).
#include <cstdint>
#include <limits>

namespace orbatlas {

using KeyframeId = std::uint64_t;
using MapPointId = std::uint64_t;
using MapId = std::uint64_t;
using SessionId = std::uint64_t;
using JobId = std::uint64_t;  // a server's upload job

inline constexpr KeyframeId kInvalidKeyframeId = std::numeric_limits<KeyframeId>::max();
inline constexpr MapPointId kInvalidMapPointId = std::numeric_limits<MapPointId>::max();
inline constexpr MapId kInvalidMapId = std::numeric_limits<MapId>::max();
inline constexpr SessionId kInvalidSessionId = std::numeric_limits<SessionId>::max();
inline constexpr JobId kInvalidJobId = std::numeric_limits<JobId>::max();

}  // namespace orbatlas
