#pragma once
// Where tracking hands new keyframes: local mapping, which belongs to the map
// (one mapper per map being mapped, fed by every session tracking in it). An
// interface so that tracking does not depend on the mapping library. The
// questions name the map the tracker is in.
#include <chrono>
#include <cstddef>
#include <memory>

#include "core/common/error.h"
#include "core/common/ids.h"
#include "core/map/keyframe.h"

namespace orbatlas {

class KeyframeSink {
 public:
  virtual ~KeyframeSink() = default;
  // True when the map's mapping has none of this session's keyframes queued or
  // in processing (ORB-SLAM's AcceptKeyFrames, per session when several map one map).
  virtual bool idle(MapId map) const = 0;
  virtual std::size_t queued(MapId map) const = 0;
  // False while the map's mapping is paused (a loop correction or a merge is
  // moving the map): tracking then makes no keyframe, as ORB-SLAM does while
  // local mapping is stopped.
  virtual bool accepting(MapId map) const = 0;
  // To the mapping of the keyframe's map. Blocks while its queue is full.
  virtual void insert(std::shared_ptr<KeyFrame> keyframe) = 0;
  // Asks the map's running local bundle adjustment to finish early when it is
  // of this session's keyframe (the session's next keyframe is waiting).
  virtual void interrupt_optimization(MapId map) = 0;
  // Waits, at most `at_most`, until the map's mapping has adjusted every
  // keyframe this session handed it (its local BA done, or skipped). True when
  // it has; false at once while the map's mapping is paused.
  virtual bool wait_until_adjusted(MapId map, std::chrono::milliseconds at_most) = 0;
};

// The sink of a localisation, which never makes a keyframe (one would be a bug).
class NoKeyframes final : public KeyframeSink {
 public:
  bool idle(MapId) const override { return true; }
  std::size_t queued(MapId) const override { return 0; }
  bool accepting(MapId) const override { return false; }
  void insert(std::shared_ptr<KeyFrame>) override { throw Error("a localisation session made a keyframe"); }
  void interrupt_optimization(MapId) override {}
  bool wait_until_adjusted(MapId, std::chrono::milliseconds) override { return true; }
};

}  // namespace orbatlas
