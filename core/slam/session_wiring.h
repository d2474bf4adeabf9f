#pragma once
// How a SLAM session is connected to what runs around it: the owner's rules for
// which maps it may enter or merge into (the server's map leases, the offline
// runner's camera rig), the thread shared for loop closing, and what to tell the
// owner after a live merge. Options stay data (settable from a file); this is
// wiring, given to the session's constructor.
#include <functional>
#include <memory>

#include "core/common/ids.h"
#include "core/common/serial_worker.h"
#include "core/loop/loop_closer.h"
#include "core/slam/mapping_workers.h"

namespace orbatlas {

struct SessionWiring {
  // Relocalisation only enters maps this accepts (empty: all).
  std::function<bool(MapId)> may_enter_map;
  // The mapping the session's keyframes go to, shared with the other sessions
  // of the owner (the server's, per camera rig; `orbatlas run` with several
  // recordings), asked for with the session's camera and mapping options (the
  // owner may make it with them, or have made it with another session's).
  // Empty: the session makes its own from its options and the fields below;
  // with it, they are the owner's business.
  std::function<std::shared_ptr<MappingWorkers>(const FrameCamera&, const MappingWorkersOptions&)> mapping;
  // Live merging only into maps this accepts (empty: all); `hold_map` must
  // agree just before a merge (empty: yes); `on_merged` is told afterwards, on
  // the loop-closing thread.
  std::function<bool(MapId)> may_merge_into;
  std::function<bool(MapId source, MapId target)> hold_map;
  std::function<void(const LiveMerge&)> on_merged;
  // Loop closing on this thread shared with other sessions (empty: its own).
  std::shared_ptr<SerialWorker> loop_worker;
};

}  // namespace orbatlas
