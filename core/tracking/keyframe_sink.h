#pragma once
// Where tracking hands new keyframes (the local mapper, in its own thread). An
// interface so that tracking does not depend on the mapping library.
#include <cstddef>
#include <memory>

#include "core/map/keyframe.h"

namespace orbatlas {

class KeyframeSink {
 public:
  virtual ~KeyframeSink() = default;
  // True when the consumer has nothing queued and is not processing (ORB-SLAM's AcceptKeyFrames).
  virtual bool idle() const = 0;
  virtual std::size_t queued() const = 0;
  // False while the consumer is paused (a loop correction is moving the map):
  // tracking then makes no keyframe, as ORB-SLAM does while local mapping is stopped.
  virtual bool accepting() const { return true; }
  // Blocks while the queue is full.
  virtual void insert(std::shared_ptr<KeyFrame> keyframe) = 0;
  // Asks a running local bundle adjustment to finish early (a keyframe is waiting).
  virtual void interrupt_optimization() = 0;
};

}  // namespace orbatlas
