#include "core/server/replica_coordinator.h"

#include <chrono>
#include <string>
#include <utility>

#include "core/common/log.h"
#include "core/persistence/wall_clock.h"

namespace orbatlas {
namespace {

std::int64_t lease_ns(double lease_s) { return static_cast<std::int64_t>(lease_s * 1e9); }

// The lease holder of a map being handed over to another replica (no session gets this id).
constexpr SessionId kHandOverLease = kInvalidSessionId - 2;

}  // namespace

void confine_ids_to_replica(Atlas& atlas, SessionRegistry& sessions, std::uint64_t replica_id) {
  IdAllocator& ids = atlas.ids();
  for (const auto& [kind, shift] :
       {std::pair{IdKind::keyframe, kReplicaKeyframeIdShift}, std::pair{IdKind::map_point, kReplicaMapPointIdShift},
        std::pair{IdKind::map, kReplicaMapIdShift}}) {
    const ReplicaIdRange range = replica_id_range(replica_id, shift);
    ids.confine(kind, range.begin, range.end);
  }
  sessions.start_ids_at(replica_id_range(replica_id, kReplicaMapIdShift).begin);
}

ReplicaCoordinator::ReplicaCoordinator(ReplicaParts parts, std::map<MapId, std::int64_t> seen_versions)
    : parts_(std::move(parts)), seen_versions_(std::move(seen_versions)) {
  ORBATLAS_CHECK(parts_.vocabulary && parts_.atlas && parts_.leases && parts_.checkpointer && parts_.replica &&
                     parts_.ownership && parts_.shared_merges && parts_.sessions && parts_.rigs && parts_.merge_camera,
                 "a replica coordinator needs every part");
}

ReplicaCoordinator::~ReplicaCoordinator() { stop(); }

void ReplicaCoordinator::start() {
  std::lock_guard lock(mutex_);
  if (stopped_ || takeover_thread_.joinable()) return;
  takeover_thread_ = std::thread([this] { take_over_until_stopped(); });
  // The merge work left with the maps this replica writes now is claimed there too.
  merge_work_thread_ = std::thread([this] { share_merge_work_until_stopped(); });
}

void ReplicaCoordinator::stop() {
  {
    std::lock_guard lock(mutex_);
    stopped_ = true;
  }
  takeover_wake_.notify_all();
  merge_work_wake_.notify_all();
  if (takeover_thread_.joinable()) takeover_thread_.join();
  if (merge_work_thread_.joinable()) merge_work_thread_.join();
}

// ---- the takeover thread

AtlasStore& ReplicaCoordinator::store() {
  if (!store_) store_.emplace(AtlasStore::open(parts_.db, parts_.vocabulary->hash()));
  return *store_;
}

void ReplicaCoordinator::load_new_sessions(AtlasStore& store, bool rigs_of_live_replicas) {
  // Sessions of replicas alive now are theirs to report; those of replicas that
  // stopped or died (and sessions from before replicas) are listed here.
  std::set<std::uint64_t> alive;
  for (const ReplicaInfo& r : parts_.replica->replicas())
    if (r.alive && !r.self) alive.insert(r.id);
  const std::map<SessionId, SessionRecord> records = store.load_session_records();
  for (const SessionInfo& info : store.load_sessions()) {
    if (parts_.sessions->contains(info.id)) continue;
    const bool live_elsewhere = alive.count(replica_of_id(info.id, kReplicaMapIdShift)) > 0;
    if (live_elsewhere && !rigs_of_live_replicas) continue;
    const auto anchors = store.load_trajectory(info.id);
    parts_.rigs->record_session(*parts_.atlas, info, anchors);  // a map keeps its first rig
    if (live_elsewhere) continue;
    const auto record = records.find(info.id);
    parts_.sessions->add_stored(
        std::make_shared<LiveSession>(
            info, record == records.end() ? std::nullopt : std::optional<SessionRecord>(record->second), anchors),
        false);
  }
}

void ReplicaCoordinator::swap_in_maps(const std::vector<std::shared_ptr<Map>>& fresh, const std::vector<MapId>& gone) {
  Atlas& atlas = *parts_.atlas;
  const auto whole = atlas.lock_maps_exclusive();
  KeyframeIndex& index = atlas.keyframe_index();
  for (const auto& map : fresh) {
    if (const auto old = atlas.replace_map(map))
      for (const auto& kf : old->keyframes()) index.erase(kf->id());
    for (const auto& kf : map->keyframes()) index.add(kf);
  }
  for (const MapId id : gone)
    if (const auto old = atlas.remove_map(id))
      for (const auto& kf : old->keyframes()) index.erase(kf->id());
}

std::vector<MapId> ReplicaCoordinator::take_over_maps() {
  const std::vector<MapId> claimed = parts_.ownership->claim_free_and_dead();
  if (claimed.empty()) return {};
  // Read again after the claim: what their last owner committed, nothing later.
  std::vector<std::shared_ptr<Map>> fresh;
  AtlasStore& db = store();
  for (const MapId id : claimed)
    if (auto map = db.load_map(*parts_.atlas, id, parts_.vocabulary)) fresh.push_back(std::move(map));
  swap_in_maps(fresh, {});
  load_new_sessions(db, true);  // the dead replica's sessions, and its maps' rigs
  parts_.ownership->ready(claimed);
  std::string names;
  for (const auto& map : fresh) {
    parts_.leases->add_free(map->id());
    names += (names.empty() ? "" : ", ") + std::to_string(map->id()) + " (" + std::to_string(map->keyframe_count()) +
             " keyframes)";
  }
  if (!fresh.empty()) log_info("replica " + std::to_string(parts_.replica->id()) + " took over map(s) " + names);
  wake_merge_work();  // and the merge work their replica left
  return claimed;
}

std::vector<MapId> ReplicaCoordinator::refresh_others_maps() {
  MapOwnership& ownership = *parts_.ownership;
  std::set<MapId> listed;
  std::vector<MapOwnership::Owned> stale;
  for (const MapOwnership::Owned& o : ownership.owners()) {
    listed.insert(o.map);
    if (ownership.owns(o.map)) continue;
    const auto seen = seen_versions_.find(o.map);
    if (seen != seen_versions_.end() && seen->second == o.version && parts_.atlas->map(o.map)) continue;
    stale.push_back(o);
  }
  // Maps of others that no replica owns any more: merged away by their owner
  // (a stored map nobody owns was claimed by take_over_maps just before).
  std::vector<MapId> gone;
  for (const auto& map : parts_.atlas->maps())
    if (!ownership.owns(map->id()) && !listed.count(map->id())) gone.push_back(map->id());
  if (stale.empty() && gone.empty()) return {};
  std::vector<std::shared_ptr<Map>> fresh;
  std::vector<MapId> read;
  AtlasStore& db = store();
  for (const MapOwnership::Owned& o : stale) {
    if (auto map = db.load_map(*parts_.atlas, o.map, parts_.vocabulary)) {
      fresh.push_back(std::move(map));
      read.push_back(o.map);
    }
    seen_versions_[o.map] = o.version;  // read at this version or later
  }
  swap_in_maps(fresh, gone);
  for (const MapId id : gone) seen_versions_.erase(id);
  if (!fresh.empty()) load_new_sessions(db, true);  // the rigs of the maps read
  return read;
}

void ReplicaCoordinator::take_over_until_stopped() {
  const auto period = std::chrono::duration<double>(parts_.lease_s);
  std::unique_lock lock(mutex_);
  while (!takeover_wake_.wait_for(lock, period, [this] { return stopped_; })) {
    lock.unlock();
    try {
      take_over_maps();
      adopt_gone_sessions_work();  // after the takeover: the maps are read here before their rows are claimed
      refresh_others_maps();
      load_new_sessions(store(), false);  // sessions of replicas that stopped or died
    } catch (const std::exception& e) {
      store_.reset();  // a new connection next time
      log_warn(std::string("replica: taking over or reading other replicas' maps failed (tried again later): ") +
               e.what());
    }
    lock.lock();
  }
}

// ---- the merge-work thread

void ReplicaCoordinator::wake_merge_work() {
  {
    std::lock_guard lock(mutex_);
    merge_work_woken_ = true;
  }
  merge_work_wake_.notify_all();
}

void ReplicaCoordinator::share_merge_work_until_stopped() {
  const auto period = std::chrono::duration<double>(parts_.lease_s);
  std::unique_lock lock(mutex_);
  while (!stopped_) {
    merge_work_wake_.wait_for(lock, period, [this] { return stopped_ || merge_work_woken_; });
    if (stopped_) break;
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

void ReplicaCoordinator::share_merge_work() {
  MapOwnership& ownership = *parts_.ownership;
  // Maps others asked for, idle here: checkpointed and handed over.
  for (const MapOwnership::Wanted& w : ownership.wanted()) hand_over_if_idle(w.map, w.by);
  if (!parts_.merger) return;  // --no-merging: the rows wait for a replica that asks for their maps
  // This replica's next row, when its worker is free (one at a time, so that
  // the rest can go to a replica whose worker is free sooner).
  if (parts_.merger->stats().pending > 0) return;
  const std::uint64_t me = parts_.replica->id();
  while (const auto row = parts_.shared_merges->claim(me)) {
    if (!ownership.owns(row->map)) {
      // Handed over (or taken over) but not read again yet: the takeover
      // thread wakes this one when it has.
      parts_.shared_merges->unclaim(row->map);
      return;
    }
    if (submit_stored_merge(*row)) return;
  }
  // Nothing of its own: ask for the map of a row that waited a lease unclaimed.
  const std::int64_t before = unix_time_ns() - lease_ns(parts_.lease_s);
  if (const auto map = parts_.shared_merges->waiting_elsewhere(me, before); map && ownership.want(*map))
    log_info("replica " + std::to_string(me) + " asks for map " + std::to_string(*map) +
             ": its merge work waits and this replica's merging worker is free");
}

bool ReplicaCoordinator::submit_stored_merge(const StoredMerge& m) {
  std::shared_ptr<const FrameCamera> cam;
  try {
    cam = parts_.merge_camera(m.settings);
  } catch (const std::exception& e) {
    log_warn("map merging: map " + std::to_string(m.map) + ": no merging (" + e.what() + ")");
    parts_.shared_merges->remove(m.map);
    return false;
  }
  {
    std::lock_guard lock(claimed_mutex_);
    claimed_merges_.insert(m.map);
  }
  log_info("map merging: map " + std::to_string(m.map) + "'s stored merge work taken by replica " +
           std::to_string(parts_.replica->id()));
  if (parts_.merger->submit(MergeRequest{m.map, cam, m.first_keyframe, m.inertial, m.single_camera})) return true;
  {
    std::lock_guard lock(claimed_mutex_);
    claimed_merges_.erase(m.map);
  }
  parts_.shared_merges->defer(m.map, unix_time_ns() + lease_ns(parts_.lease_s));
  return false;
}

std::vector<MapId> ReplicaCoordinator::store_merge_work(const std::vector<MapId>& maps, const SessionStart& start) {
  std::vector<MapId> not_stored;
  for (const MapId map : maps) {
    try {
      parts_.shared_merges->add(
          StoredMerge{map, start.settings, start.first_keyframe, start.inertial, start.rig.monocular});
    } catch (const std::exception& e) {
      log_warn("map merging: cannot store the merge work of map " + std::to_string(map) + " (done here): " + e.what());
      not_stored.push_back(map);
    }
  }
  wake_merge_work();
  return not_stored;
}

void ReplicaCoordinator::merge_done(MapId map) {
  try {
    parts_.shared_merges->remove(map);
  } catch (const std::exception& e) {
    log_warn("map merging: the stored merge work of map " + std::to_string(map) + " stays: " + e.what());
  }
  {
    std::lock_guard lock(claimed_mutex_);
    claimed_merges_.erase(map);
  }
  wake_merge_work();  // the next row
}

void ReplicaCoordinator::merge_put_off(MapId source, MapId target) {
  {
    std::lock_guard lock(claimed_mutex_);
    claimed_merges_.erase(source);
  }
  try {
    if (!parts_.ownership->owns(target) && parts_.ownership->want(target))
      log_info("replica " + std::to_string(parts_.replica->id()) + " asks for map " + std::to_string(target) +
               ": map " + std::to_string(source) + "'s merge found its place there");
    parts_.shared_merges->defer(source, unix_time_ns() + lease_ns(parts_.lease_s));
  } catch (const std::exception& e) {
    log_warn("map merging: map " + std::to_string(source) + "'s merge work is not put back (" + e.what() +
             "); it waits until this replica stops");
  }
  wake_merge_work();
}

void ReplicaCoordinator::begin_session_work(SessionId id, const StoredMerge& request) {
  try {
    parts_.shared_merges->begin_session(id, parts_.replica->id(), request);
  } catch (const std::exception& e) {
    log_warn("session " + std::to_string(id) + ": its merge work is not stored while it maps (" + e.what() +
             "); should this replica die first, nobody merges its maps");
  }
}

void ReplicaCoordinator::end_session_work(SessionId id) {
  try {
    parts_.shared_merges->end_session(id);
  } catch (const std::exception& e) {
    log_warn("session " + std::to_string(id) + ": its stored merge work stays (" + e.what() +
             "); another replica adopts it once this one stops");
  }
}

void ReplicaCoordinator::adopt_gone_sessions_work() {
  const std::vector<MapId> maps = parts_.shared_merges->adopt_sessions_of_gone_replicas();
  if (maps.empty()) return;
  std::string names;
  for (const MapId map : maps) names += (names.empty() ? "" : ", ") + std::to_string(map);
  log_info("replica " + std::to_string(parts_.replica->id()) +
           ": sessions whose replica stopped or died while they mapped leave merge work for map(s) " + names);
  wake_merge_work();
}

bool ReplicaCoordinator::hand_over_if_idle(MapId map, std::uint64_t to) {
  {
    std::lock_guard lock(claimed_mutex_);
    if (claimed_merges_.count(map)) return false;  // this replica's worker has its merge work
  }
  // Its own merge waits for another map (put off): two replicas waiting for
  // each other's maps would swap them for ever, so only the one with the
  // lower id gets it.
  if (to > parts_.replica->id() && parts_.shared_merges->put_off(map)) return false;
  // Nothing works in it here (no session, no merge) while it is checkpointed and handed over.
  MapLeases& leases = *parts_.leases;
  if (!parts_.ownership->owns(map) || !leases.claim_exclusive(kHandOverLease, map)) return false;
  struct ReleaseLease {
    MapLeases& leases;
    ~ReleaseLease() { leases.release_all(kHandOverLease); }
  } release{leases};
  if (!parts_.checkpointer->checkpoint_now()) {
    log_warn("replica: map " + std::to_string(map) + " is not handed over to replica " + std::to_string(to) +
             ": its checkpoint failed (" + parts_.checkpointer->stats().last_error + ")");
    return false;
  }
  if (!parts_.ownership->hand_over(map, to)) return false;
  leases.forget(map);  // another replica's now: read here, never mapped
  log_info("replica " + std::to_string(parts_.replica->id()) + " handed map " + std::to_string(map) +
           " over to replica " + std::to_string(to) + " (asked for it)");
  return true;
}

}  // namespace orbatlas
