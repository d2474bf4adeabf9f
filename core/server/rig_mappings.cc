#include "core/server/rig_mappings.h"

#include <algorithm>
#include <string>

#include "core/common/log.h"

namespace orbatlas {

RigMappings::RigMappings(std::size_t loop_queue, int nice)
    : loop_worker_(std::make_shared<SerialWorker>(loop_queue, nice, "loop closing")) {}

RigMappings::~RigMappings() {
  try {
    finish();
  } catch (const std::exception& e) {
    log_warn(std::string("mapping stopped with an error: ") + e.what());
  }
}

std::shared_ptr<MappingWorkers> RigMappings::for_rig(const MapRig& rig, const Make& make) {
  std::lock_guard lock(mutex_);
  for (const Entry& e : entries_)
    if (same_mapping_rig(e.rig, rig)) return e.workers;
  auto workers = make(loop_worker_);
  entries_.push_back({rig, workers});
  return workers;
}

std::shared_ptr<MappingWorkers> RigMappings::find(const MapRig& rig) const {
  std::lock_guard lock(mutex_);
  for (const Entry& e : entries_)
    if (same_mapping_rig(e.rig, rig)) return e.workers;
  return nullptr;
}

RigMappings::Totals RigMappings::totals() const {
  Totals out;
  std::lock_guard lock(mutex_);
  for (const Entry& e : entries_) {
    out.errors += e.workers->errors();
    out.mapped_keyframes += e.workers->mapping_stats().keyframes;
    const LoopClosingStats loop = e.workers->loop_stats();
    out.loops += loop.loops.size();
    out.global_adjustments += loop.global_adjustments.size();
    out.stream_end_adjustments +=
        std::count_if(loop.global_adjustments.begin(), loop.global_adjustments.end(),
                      [](const GlobalAdjustmentRun& g) { return g.cause == GlobalAdjustmentCause::kStreamEnd; });
    out.mappers += e.workers->mapped_maps().size();
  }
  return out;
}

void RigMappings::finish() {
  std::vector<Entry> entries;
  {
    std::lock_guard lock(mutex_);
    entries.swap(entries_);
  }
  for (const Entry& e : entries) {
    try {
      e.workers->finish();
    } catch (const std::exception& ex) {
      log_warn(std::string("mapping stopped with an error: ") + ex.what());
    }
  }
  loop_worker_->stop();
}

}  // namespace orbatlas
