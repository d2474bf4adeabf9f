#include "core/map/redundancy_tracker.h"

#include <utility>

namespace orbatlas {

void track_attach(ObserverRecords& records, KeyframeId id, ObserverRecord record) {
  int mine = 0;
  for (auto& [other_id, other] : records) {
    if (other.level <= record.level + 1) ++mine;  // the other observer counts for the newcomer
    if (record.level <= other.level + 1) {        // the newcomer counts for the other observer
      if (++other.finer_observers == kRedundancyMinObservers) other.redundant_counter->fetch_add(1);
    }
  }
  record.finer_observers = mine;
  if (mine >= kRedundancyMinObservers) record.redundant_counter->fetch_add(1);
  records.emplace(id, std::move(record));
}

void track_detach(ObserverRecords& records, KeyframeId id) {
  const auto it = records.find(id);
  if (it == records.end()) return;
  if (it->second.finer_observers >= kRedundancyMinObservers) it->second.redundant_counter->fetch_sub(1);
  const int level = it->second.level;
  records.erase(it);
  for (auto& [other_id, other] : records) {
    if (level <= other.level + 1) {
      if (other.finer_observers-- == kRedundancyMinObservers) other.redundant_counter->fetch_sub(1);
    }
  }
}

}  // namespace orbatlas
