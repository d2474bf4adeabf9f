#pragma once
// How tracking asks to be relocalised when it has lost its map (implemented over
// the atlas-wide keyframe index in core/relocalization; an interface so that tracking
// does not depend on place recognition).
#include <memory>
#include <optional>

#include "core/map/keyframe.h"
#include "core/tracking/frame.h"

namespace orbatlas {

struct Relocalized {
  MapId map = 0;
  std::shared_ptr<KeyFrame> keyframe;  // the keyframe it was recognised from
};

class FrameRelocalizer {
 public:
  virtual ~FrameRelocalizer() = default;
  // On success the frame holds its pose and map-point associations.
  virtual std::optional<Relocalized> relocalize(Frame& frame) = 0;
};

}  // namespace orbatlas
