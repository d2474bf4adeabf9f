// AtlasService as one replica of a shared (PostgreSQL) atlas
// (docs/scaling.md "Replicas"): the replicas it lists, and the takeover of the
// maps nobody writes (their replica died) with the sessions it did not know.
#include <chrono>
#include <map>
#include <set>
#include <utility>
#include <string>
#include <vector>

#include "core/common/log.h"
#include "core/server/atlas_service.h"
#include "core/server/service_error.h"
#include "core/server/shared_merges.h"

namespace orbatlas {

std::vector<ReplicaInfo> AtlasService::replicas() const {
  try {
    return replica_->replicas();
  } catch (const std::exception& e) {
    throw ServiceError(ServiceErrorKind::kUnavailable, "database_unavailable",
                       std::string("cannot read the replicas from the atlas's database: ") + e.what());
  }
}

void AtlasService::load_new_sessions(AtlasStore& store, bool rigs_of_live_replicas) {
  // Sessions of replicas alive now are theirs to report; those of replicas that
  // stopped or died (and sessions from before replicas) are listed here.
  std::set<std::uint64_t> alive;
  for (const ReplicaInfo& r : replica_->replicas())
    if (r.alive && !r.self) alive.insert(r.id);
  const std::map<SessionId, SessionRecord> records = store.load_session_records();
  for (const SessionInfo& info : store.load_sessions()) {
    {
      std::lock_guard lock(mutex_);
      if (sessions_.count(info.id)) continue;
    }
    const bool live_elsewhere = alive.count(replica_of_id(info.id, kReplicaMapIdShift)) > 0;
    if (live_elsewhere && !rigs_of_live_replicas) continue;
    const auto anchors = store.load_trajectory(info.id);
    std::map<MapId, MapRig> rigs;
    record_map_rigs(atlas_, info, anchors, rigs);
    {
      std::lock_guard lock(rigs_mutex_);
      for (auto& [map, rig] : rigs) map_rigs_.try_emplace(map, std::move(rig));  // a map keeps its first rig
    }
    if (live_elsewhere) continue;
    const auto record = records.find(info.id);
    auto session = std::make_shared<LiveSession>(
        info, record == records.end() ? std::nullopt : std::optional<SessionRecord>(record->second), anchors);
    std::lock_guard lock(mutex_);
    sessions_.try_emplace(info.id, std::move(session));
  }
}

AtlasStore& AtlasService::replica_store() {
  if (!replica_store_) replica_store_.emplace(AtlasStore::open(options_.db, vocabulary_.hash()));
  return *replica_store_;
}

void AtlasService::start_as_replica(const std::vector<MapId>& claimed) {
  const std::uint64_t r = replica_->id();
  IdAllocator& ids = atlas_.ids();
  for (const auto& [kind, shift] :
       {std::pair{IdKind::keyframe, kReplicaKeyframeIdShift}, std::pair{IdKind::map_point, kReplicaMapPointIdShift},
        std::pair{IdKind::map, kReplicaMapIdShift}}) {
    const ReplicaIdRange range = replica_id_range(r, shift);
    ids.confine(kind, range.begin, range.end);
  }
  next_session_ = replica_id_range(r, kReplicaMapIdShift).begin;  // before any thread: no lock needed yet
  ownership_->ready(claimed);
  if (!claimed.empty())
    log_info("replica " + std::to_string(r) + " writes " + std::to_string(claimed.size()) +
             " stored map(s) that no live replica writes (their replica stopped or died, or none ever did)");
}

void AtlasService::swap_in_maps(const std::vector<std::shared_ptr<Map>>& fresh, const std::vector<MapId>& gone) {
  const auto whole = atlas_.lock_maps_exclusive();
  KeyframeIndex& index = atlas_.keyframe_index();
  for (const auto& map : fresh) {
    if (const auto old = atlas_.replace_map(map))
      for (const auto& kf : old->keyframes()) index.erase(kf->id());
    for (const auto& kf : map->keyframes()) index.add(kf);
  }
  for (const MapId id : gone)
    if (const auto old = atlas_.remove_map(id))
      for (const auto& kf : old->keyframes()) index.erase(kf->id());
}

std::vector<MapId> AtlasService::take_over_maps() {
  if (!ownership_) return {};
  const std::vector<MapId> claimed = ownership_->claim_free_and_dead();
  if (claimed.empty()) return {};
  // Read again after the claim: what their last owner committed, nothing later.
  std::vector<std::shared_ptr<Map>> fresh;
  AtlasStore& store = replica_store();
  for (const MapId id : claimed)
    if (auto map = store.load_map(atlas_, id, &vocabulary_)) fresh.push_back(std::move(map));
  swap_in_maps(fresh, {});
  load_new_sessions(store, true);  // the dead replica's sessions, and its maps' rigs
  ownership_->ready(claimed);
  std::string names;
  for (const auto& map : fresh) {
    leases_.add_free(map->id());
    names += (names.empty() ? "" : ", ") + std::to_string(map->id()) + " (" + std::to_string(map->keyframe_count()) +
             " keyframes)";
  }
  if (!fresh.empty()) log_info("replica " + std::to_string(replica_->id()) + " took over map(s) " + names);
  wake_merge_work();  // and the merge work their replica left
  return claimed;
}

std::vector<MapId> AtlasService::refresh_others_maps() {
  if (!ownership_) return {};
  std::set<MapId> listed;
  std::vector<MapOwnership::Owned> stale;
  for (const MapOwnership::Owned& o : ownership_->owners()) {
    listed.insert(o.map);
    if (ownership_->owns(o.map)) continue;
    const auto seen = seen_versions_.find(o.map);
    if (seen != seen_versions_.end() && seen->second == o.version && atlas_.map(o.map)) continue;
    stale.push_back(o);
  }
  // Maps of others that no replica owns any more: merged away by their owner
  // (a stored map nobody owns was claimed by take_over_maps just before).
  std::vector<MapId> gone;
  for (const auto& map : atlas_.maps())
    if (!ownership_->owns(map->id()) && !listed.count(map->id())) gone.push_back(map->id());
  if (stale.empty() && gone.empty()) return {};
  std::vector<std::shared_ptr<Map>> fresh;
  std::vector<MapId> read;
  AtlasStore& store = replica_store();
  for (const MapOwnership::Owned& o : stale) {
    if (auto map = store.load_map(atlas_, o.map, &vocabulary_)) {
      fresh.push_back(std::move(map));
      read.push_back(o.map);
    }
    seen_versions_[o.map] = o.version;  // read at this version or later
  }
  swap_in_maps(fresh, gone);
  for (const MapId id : gone) seen_versions_.erase(id);
  if (!fresh.empty()) load_new_sessions(store, true);  // the rigs of the maps read
  return read;
}

void AtlasService::take_over_until_stopped() {
  const auto period = std::chrono::duration<double>(options_.replica.lease_s);
  std::unique_lock lock(mutex_);
  while (!takeover_wake_.wait_for(lock, period, [this] { return shut_down_; })) {
    lock.unlock();
    try {
      take_over_maps();
      adopt_gone_sessions_work();  // after the takeover: the maps are read here before their rows are claimed
      refresh_others_maps();
      load_new_sessions(replica_store(), false);  // sessions of replicas that stopped or died
    } catch (const std::exception& e) {
      replica_store_.reset();  // a new connection next time
      log_warn(std::string("replica: taking over or reading other replicas' maps failed (tried again later): ") +
               e.what());
    }
    lock.lock();
  }
}

}  // namespace orbatlas
