#pragma once
// Walking the inertial chain of a visual-inertial session's keyframes: each
// keyframe links to the previous one of its session in its map by the IMU
// preintegrated between them (KeyFrame::inertial_link).
#include <cstddef>
#include <limits>
#include <memory>
#include <vector>

#include "core/map/keyframe.h"

namespace orbatlas {

// The chain of keyframes linked by preintegrated IMU that ends at `newest`,
// oldest first, at most `max_keyframes` long (culled keyframes were skipped
// when they were culled; the chain stops at a broken link or another map).
std::vector<std::shared_ptr<KeyFrame>> inertial_chain(
    const std::shared_ptr<KeyFrame>& newest, std::size_t max_keyframes = std::numeric_limits<std::size_t>::max());

}  // namespace orbatlas
