// AtlasService's part in map merging: a finished session's maps handed to the
// merging worker (or stored as merge work in a shared atlas), which maps may be
// merged or mapped together (their rigs), and the merges done, live and by the
// worker.
#include <memory>
#include <string>
#include <vector>

#include "core/common/log.h"
#include "core/server/atlas_service.h"
#include "core/server/atlas_service_localizer.h"
#include "core/server/session_rules.h"
#include "core/server/shared_merges.h"

namespace orbatlas {

std::shared_ptr<const FrameCamera> AtlasService::merge_camera(const SettingsSource& settings) {
  const std::shared_ptr<LocalizerContext> context = localizer_for(settings);
  // The camera shares the context's ownership: it lives while a request holds it.
  return std::shared_ptr<const FrameCamera>(context, &context->map_cam);
}

void AtlasService::submit_merges(SessionId id, const std::vector<MapId>& maps) {
  if ((!merger_ && !shared_merges_) || maps.empty()) return;
  SessionStart start;
  bool shutting_down = false;
  {
    std::lock_guard lock(mutex_);
    const auto it = session_starts_.find(id);
    if (it == session_starts_.end()) return;
    start = it->second;
    shutting_down = shut_down_;
  }
  // A shared atlas keeps the work in the database: the merge-work thread
  // claims it for this replica's worker, or hands the map to a replica that
  // asks for it (also when this replica does not merge, or stops first).
  std::vector<MapId> direct = maps;
  if (shared_merges_) {
    direct.clear();
    for (const MapId map : maps) {
      try {
        shared_merges_->add(
            StoredMerge{map, start.settings, start.first_keyframe, start.inertial, start.rig.monocular});
      } catch (const std::exception& e) {
        log_warn("map merging: cannot store the merge work of map " + std::to_string(map) +
                 " (done here): " + e.what());
        direct.push_back(map);
      }
    }
    wake_merge_work();
  }
  if (!merger_ || shutting_down || direct.empty()) return;
  std::shared_ptr<const FrameCamera> cam;
  try {
    cam = merge_camera(start.settings);
  } catch (const std::exception& e) {
    log_warn("session " + std::to_string(id) + ": no merging (" + e.what() + ")");
    return;
  }
  for (const MapId map : direct)
    merger_->submit(MergeRequest{map, cam, start.first_keyframe, start.inertial, start.rig.monocular});
}

bool AtlasService::rigs_match(MapId source, MapId target) const {
  // A shared atlas: only maps this replica writes are merged; a place found in
  // another replica's map puts the work off until that map is handed over
  // (MapMergeWorker::set_put_off).
  if (ownership_ && !ownership_->owns(source)) return false;
  // Maps of one rig; a single camera's map goes into a stereo one of its rig,
  // not the other way (merge_maps gives the first the target's scale). Maps
  // of single-camera sessions have a rig only in the server run that made
  // them (record_map_rigs).
  std::lock_guard lock(rigs_mutex_);
  const auto a = map_rigs_.find(source);
  const auto b = map_rigs_.find(target);
  return a != map_rigs_.end() && b != map_rigs_.end() && (a->second.monocular || !b->second.monocular) &&
         same_rig(a->second.cameras, b->second.cameras);
}

bool AtlasService::cameras_match(const CameraRig& cameras, MapId target) const {
  std::lock_guard lock(rigs_mutex_);
  const auto b = map_rigs_.find(target);
  return b != map_rigs_.end() && same_rig(cameras, b->second.cameras);
}

bool AtlasService::mapping_rig_matches(const MapRig& rig, MapId target) const {
  if (ownership_ && !ownership_->owns(target)) return false;  // another replica's map: read, never mapped
  {
    std::lock_guard lock(rigs_mutex_);
    const auto b = map_rigs_.find(target);
    if (b == map_rigs_.end() || !may_map_into(rig, b->second)) return false;
  }
  // One local mapping per map: the sessions mapping in it now map as `rig` does
  // (a monocular session and a stereo one never map one map at once).
  for (const SessionId holder : leases_.holders(target))
    if (holder != kMergeWorkerLease && !same_mapping_rig(mapping_rig(holder), rig)) return false;
  return true;
}

MapRig AtlasService::mapping_rig(SessionId id) const {
  std::lock_guard lock(mutex_);
  const auto it = session_starts_.find(id);
  if (it != session_starts_.end()) return it->second.rig;
  const auto s = sessions_.find(id);  // a stored session (this run did not start it)
  if (s == sessions_.end()) return {};
  const SensorType sensor = s->second->info().sensor;
  return MapRig{s->second->info().cameras, sensor == SensorType::kStereoInertial, is_single_camera(sensor)};
}

void AtlasService::merged_live(const LiveMerge& merge) {
  // The sessions that were in the merged map (they hold the joined one now).
  const std::vector<SessionId> moved = leases_.holders(merge.merge.source);
  const SessionId session = moved.empty() ? kInvalidSessionId : moved.front();
  leases_.forget(merge.merge.source);
  {
    std::lock_guard lock(rigs_mutex_);
    map_rigs_.erase(merge.merge.source);
  }
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
  {
    std::lock_guard lock(rigs_mutex_);
    map_rigs_.erase(record.merge.source);
  }
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
