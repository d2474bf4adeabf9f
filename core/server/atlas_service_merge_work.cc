// AtlasService's share of a shared (PostgreSQL) atlas's merge work
// (docs/scaling.md "Replicas"): this replica's merge rows are claimed for its
// merging worker one at a time, as the worker becomes free; a replica with a
// free worker and nothing of its own asks for a map whose row waited a lease
// unclaimed; and the maps other replicas ask for (such a row, or the place
// their merge found) are handed over once nothing works in them here.
#include <chrono>
#include <string>

#include "core/common/log.h"
#include "core/persistence/wall_clock.h"
#include "core/server/atlas_service.h"
#include "core/server/shared_merges.h"

namespace orbatlas {

namespace {

std::int64_t lease_ns(double lease_s) { return static_cast<std::int64_t>(lease_s * 1e9); }

}  // namespace

void AtlasService::wake_merge_work() {
  {
    std::lock_guard lock(mutex_);
    merge_work_woken_ = true;
  }
  merge_work_wake_.notify_all();
}

void AtlasService::share_merge_work_until_stopped() {
  const auto period = std::chrono::duration<double>(options_.replica.lease_s);
  std::unique_lock lock(mutex_);
  while (!shut_down_) {
    merge_work_wake_.wait_for(lock, period, [this] { return shut_down_ || merge_work_woken_; });
    if (shut_down_) break;
    merge_work_woken_ = false;
    lock.unlock();
    try {
      share_merge_work();
    } catch (const std::exception& e) {
      log_warn(std::string("replica: sharing the merge work failed (tried again later): ") + e.what());
    }
    lock.lock();
  }
}

void AtlasService::share_merge_work() {
  // Maps others asked for, idle here: checkpointed and handed over.
  for (const MapOwnership::Wanted& w : ownership_->wanted()) hand_over_if_idle(w.map, w.by);
  if (!merger_) return;  // --no-merging: the rows wait for a replica that asks for their maps
  // This replica's next row, when its worker is free (one at a time, so that
  // the rest can go to a replica whose worker is free sooner).
  if (merger_->stats().pending > 0) return;
  const std::uint64_t me = replica_->id();
  while (const auto row = shared_merges_->claim(me)) {
    if (!ownership_->owns(row->map)) {
      // Handed over (or taken over) but not read again yet: the takeover
      // thread wakes this one when it has.
      shared_merges_->unclaim(row->map);
      return;
    }
    if (submit_stored_merge(*row)) return;
  }
  // Nothing of its own: ask for the map of a row that waited a lease unclaimed.
  const std::int64_t before = unix_time_ns() - lease_ns(options_.replica.lease_s);
  if (const auto map = shared_merges_->waiting_elsewhere(me, before); map && ownership_->want(*map))
    log_info("replica " + std::to_string(me) + " asks for map " + std::to_string(*map) +
             ": its merge work waits and this replica's merging worker is free");
}

bool AtlasService::submit_stored_merge(const StoredMerge& m) {
  std::shared_ptr<const FrameCamera> cam;
  try {
    cam = merge_camera(m.settings);
  } catch (const std::exception& e) {
    log_warn("map merging: map " + std::to_string(m.map) + ": no merging (" + e.what() + ")");
    shared_merges_->remove(m.map);
    return false;
  }
  {
    std::lock_guard lock(merge_work_mutex_);
    claimed_merges_.insert(m.map);
  }
  log_info("map merging: map " + std::to_string(m.map) + "'s stored merge work taken by replica " +
           std::to_string(replica_->id()));
  if (merger_->submit(MergeRequest{m.map, cam, m.first_keyframe, m.inertial, m.single_camera})) return true;
  {
    std::lock_guard lock(merge_work_mutex_);
    claimed_merges_.erase(m.map);
  }
  shared_merges_->defer(m.map, unix_time_ns() + lease_ns(options_.replica.lease_s));
  return false;
}

void AtlasService::merge_put_off(MapId source, MapId target) {
  {
    std::lock_guard lock(merge_work_mutex_);
    claimed_merges_.erase(source);
  }
  try {
    if (!ownership_->owns(target) && ownership_->want(target))
      log_info("replica " + std::to_string(replica_->id()) + " asks for map " + std::to_string(target) + ": map " +
               std::to_string(source) + "'s merge found its place there");
    shared_merges_->defer(source, unix_time_ns() + lease_ns(options_.replica.lease_s));
  } catch (const std::exception& e) {
    log_warn("map merging: map " + std::to_string(source) + "'s merge work is not put back (" + e.what() +
             "); it waits until this replica stops");
  }
  wake_merge_work();
}

void AtlasService::begin_session_work(SessionId id, const StoredMerge& request) {
  if (!shared_merges_) return;
  try {
    shared_merges_->begin_session(id, replica_->id(), request);
  } catch (const std::exception& e) {
    log_warn("session " + std::to_string(id) + ": its merge work is not stored while it maps (" + e.what() +
             "); should this replica die first, nobody merges its maps");
  }
}

void AtlasService::end_session_work(SessionId id) {
  if (!shared_merges_) return;
  try {
    shared_merges_->end_session(id);
  } catch (const std::exception& e) {
    log_warn("session " + std::to_string(id) + ": its stored merge work stays (" + e.what() +
             "); another replica adopts it once this one stops");
  }
}

void AtlasService::adopt_gone_sessions_work() {
  if (!shared_merges_) return;
  const std::vector<MapId> maps = shared_merges_->adopt_sessions_of_gone_replicas();
  if (maps.empty()) return;
  std::string names;
  for (const MapId map : maps) names += (names.empty() ? "" : ", ") + std::to_string(map);
  log_info("replica " + std::to_string(replica_->id()) +
           ": sessions whose replica stopped or died while they mapped leave merge work for map(s) " + names);
  wake_merge_work();
}

bool AtlasService::hand_over_if_idle(MapId map, std::uint64_t to) {
  {
    std::lock_guard lock(merge_work_mutex_);
    if (claimed_merges_.count(map)) return false;  // this replica's worker has its merge work
  }
  // Its own merge waits for another map (put off): two replicas waiting for
  // each other's maps would swap them for ever, so only the one with the
  // lower id gets it.
  if (to > replica_->id() && shared_merges_->put_off(map)) return false;
  // Nothing works in it here (no session, no merge) while it is checkpointed and handed over.
  if (!ownership_->owns(map) || !leases_.claim_exclusive(kHandOverLease, map)) return false;
  struct ReleaseLease {
    MapLeases& leases;
    ~ReleaseLease() { leases.release_all(kHandOverLease); }
  } release{leases_};
  if (!checkpointer_->checkpoint_now()) {
    log_warn("replica: map " + std::to_string(map) + " is not handed over to replica " + std::to_string(to) +
             ": its checkpoint failed (" + checkpointer_->stats().last_error + ")");
    return false;
  }
  if (!ownership_->hand_over(map, to)) return false;
  leases_.forget(map);  // another replica's now: read here, never mapped
  log_info("replica " + std::to_string(replica_->id()) + " handed map " + std::to_string(map) + " over to replica " +
           std::to_string(to) + " (asked for it)");
  return true;
}

}  // namespace orbatlas
