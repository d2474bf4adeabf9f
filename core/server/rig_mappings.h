#pragma once
// The mapping of every camera rig the server's mapping sessions use: one
// MappingWorkers (local mapping per map, loop closing) per rig and IMU use,
// shared by that rig's sessions and made with the first one's options
// (sessions that fuse an IMU need local mapping that initialises it), and the
// one loop-closing thread all of them share. Thread-safe; its mutex takes
// MappingWorkers' (figures) under it and nothing of the service.
#include <cstddef>
#include <functional>
#include <memory>
#include <mutex>
#include <vector>

#include "core/persistence/map_rigs.h"
#include "core/slam/mapping_workers.h"

namespace orbatlas {

class RigMappings {
 public:
  // `loop_queue`: keyframes waiting for the loop-closing thread (more are
  // skipped, counted in the sessions' loop statistics); `nice`: its priority.
  RigMappings(std::size_t loop_queue, int nice);
  ~RigMappings();  // finish()
  RigMappings(const RigMappings&) = delete;
  RigMappings& operator=(const RigMappings&) = delete;

  // The mapping of `rig` (made by `make` with the shared loop-closing thread
  // in its wiring when it is the first).
  using Make = std::function<std::shared_ptr<MappingWorkers>(const std::shared_ptr<SerialWorker>& loop_worker)>;
  std::shared_ptr<MappingWorkers> for_rig(const MapRig& rig, const Make& make);
  std::shared_ptr<MappingWorkers> find(const MapRig& rig) const;  // null when none

  struct Totals {
    std::size_t errors = 0, mapped_keyframes = 0, loops = 0, global_adjustments = 0, stream_end_adjustments = 0;
    std::size_t mappers = 0;  // maps whose local mapping runs now
  };
  Totals totals() const;

  // Every mapping finishes (a running global adjustment is waited for), then
  // the loop-closing thread stops. Errors are logged. Idempotent.
  void finish();

 private:
  struct Entry {
    MapRig rig;
    std::shared_ptr<MappingWorkers> workers;
  };
  const std::shared_ptr<SerialWorker> loop_worker_;
  mutable std::mutex mutex_;  // guards entries_
  std::vector<Entry> entries_;
};

}  // namespace orbatlas
