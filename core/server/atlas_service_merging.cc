// AtlasService's part in map merging: a finished session's maps handed to the
// merging worker (or stored as merge work in a shared atlas), which maps may be
// merged or mapped together (their rigs), and the merges done, live and by the
// worker.
#include <memory>
#include <string>
#include <vector>

#include "core/common/log.h"
#include "core/server/atlas_service.h"
#include "core/server/session_rules.h"

namespace orbatlas {

void AtlasService::submit_merges(SessionId id, const std::vector<MapId>& maps) {
  if ((!merger_ && !replicas_) || maps.empty()) return;
  const std::optional<SessionStart> start = sessions_.start_of(id);
  if (!start) return;
  // A shared atlas keeps the work in the database: the merge-work thread
  // claims it for this replica's worker, or hands the map to a replica that
  // asks for it (also when this replica does not merge, or stops first).
  const std::vector<MapId> direct = replicas_ ? replicas_->store_merge_work(maps, *start) : maps;
  if (!merger_ || sessions_.stopped() || direct.empty()) return;
  std::shared_ptr<const FrameCamera> cam;
  try {
    cam = localizers_.map_camera(start->settings);
  } catch (const std::exception& e) {
    log_warn("session " + std::to_string(id) + ": no merging (" + e.what() + ")");
    return;
  }
  for (const MapId map : direct)
    merger_->submit(MergeRequest{map, cam, start->first_keyframe, start->inertial, start->rig.monocular});
}

bool AtlasService::rigs_match(MapId source, MapId target) const {
  // A shared atlas: only maps this replica writes are merged; a place found in
  // another replica's map puts the work off until that map is handed over
  // (MapMergeWorker::set_put_off).
  if (ownership_ && !ownership_->owns(source)) return false;
  // Maps of one rig; a single camera's map goes into a stereo one of its rig,
  // not the other way (merge_maps gives the first the target's scale).
  return rigs_.may_merge(source, target);
}

bool AtlasService::mapping_rig_matches(const MapRig& rig, MapId target) const {
  if (ownership_ && !ownership_->owns(target)) return false;  // another replica's map: read, never mapped
  if (!rigs_.may_map(rig, target)) return false;
  // One local mapping per map: the sessions mapping in it now map as `rig` does
  // (a monocular session and a stereo one never map one map at once).
  for (const SessionId holder : leases_.holders(target))
    if (holder != kMergeWorkerLease && !same_mapping_rig(sessions_.mapping_rig(holder), rig)) return false;
  return true;
}

void AtlasService::merged_live(const LiveMerge& merge) {
  // The sessions that were in the merged map (they hold the joined one now).
  const std::vector<SessionId> moved = leases_.holders(merge.merge.source);
  const SessionId session = moved.empty() ? kInvalidSessionId : moved.front();
  leases_.forget(merge.merge.source);
  rigs_.forget(merge.merge.source);
  {
    // Its own leaf lock, not mutex_: this runs on the loop-closing thread, which a
    // session's finish waits for while holding that session's mutex, and mutex_ is
    // held while sessions are asked for their state (a cycle if taken here).
    std::lock_guard lock(live_merges_mutex_);
    push_recent(live_merges_, LiveMergeRecord{session, merge});
    ++live_merges_total_;
  }
  // Stored by the next periodic checkpoint (not waited for here: this is the
  // loop-closing thread every session shares).
  checkpointer_->notify_keyframe();
}

void AtlasService::merged(const MergeRecord& record) {
  rigs_.forget(record.merge.source);
  if (!checkpointer_->checkpoint_now())
    log_warn("the merge of map " + std::to_string(record.merge.source) +
             " is not stored yet: " + checkpointer_->stats().last_error + " (retried at the next checkpoint)");
}

MergesReport AtlasService::merges() const {
  MergesReport out;
  if (!merger_) return out;
  out.enabled = true;
  {
    std::lock_guard lock(live_merges_mutex_);
    out.live_merges = live_merges_;
    out.live_merges_total = live_merges_total_;
  }
  out.worker = merger_->stats();
  return out;
}

}  // namespace orbatlas
