#pragma once
// This server's part as one replica of a shared (PostgreSQL) atlas
// (docs/scaling.md "Replicas"), on two threads of its own:
// - the takeover thread, every lease: claims the maps nobody writes (their
//   replica died or stopped) and reads them again, adopts the merge work of
//   sessions whose replica went, reads again the maps other replicas changed
//   or made (and drops those they merged away), and lists the sessions it did
//   not know;
// - the merge-work thread, woken by a finished session's merge rows, by the
//   merging worker when it is done with one, and every lease: hands the maps
//   other replicas ask for over once nothing works in them here, claims this
//   replica's next merge row when its merging worker is free, and asks for the
//   map of a row that waited a lease when it has nothing of its own.
// Its mutex (with the wake-up) is taken under nothing and guards only the
// stop flag and the wake-up; claimed_mutex_ is a leaf.
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <thread>
#include <vector>

#include "core/map/atlas.h"
#include "core/persistence/atlas_checkpointer.h"
#include "core/persistence/atlas_store.h"
#include "core/server/map_leases.h"
#include "core/server/map_merge_worker.h"
#include "core/server/map_ownership.h"
#include "core/server/map_rig_registry.h"
#include "core/server/replica_registry.h"
#include "core/server/session_registry.h"
#include "core/server/shared_merges.h"
#include "core/vocabulary/vocabulary.h"

namespace orbatlas {

// What the coordinator works with; every part outlives it.
struct ReplicaParts {
  std::filesystem::path db;
  double lease_s = 0.0;
  const Vocabulary* vocabulary = nullptr;
  Atlas* atlas = nullptr;
  MapLeases* leases = nullptr;
  AtlasCheckpointer* checkpointer = nullptr;
  const ReplicaRegistry* replica = nullptr;
  MapOwnership* ownership = nullptr;
  SharedMerges* shared_merges = nullptr;
  MapMergeWorker* merger = nullptr;  // null when this server does not merge
  SessionRegistry* sessions = nullptr;
  MapRigRegistry* rigs = nullptr;
  // The camera to merge the maps of these settings with (ServiceError when unusable).
  std::function<std::shared_ptr<const FrameCamera>(const SettingsSource&)> merge_camera;
};

// A shared atlas, at start before the load: ids (keyframes, points, maps,
// sessions) come from this replica's own ranges.
void confine_ids_to_replica(Atlas& atlas, SessionRegistry& sessions, std::uint64_t replica_id);

class ReplicaCoordinator {
 public:
  // `seen_versions`: the version of each map as the start read it.
  ReplicaCoordinator(ReplicaParts parts, std::map<MapId, std::int64_t> seen_versions);
  ~ReplicaCoordinator();  // stop()
  ReplicaCoordinator(const ReplicaCoordinator&) = delete;
  ReplicaCoordinator& operator=(const ReplicaCoordinator&) = delete;

  void start();  // the two threads
  void stop();   // joins them; idempotent

  // A finished session's maps as merge work in the database; returns those
  // that could not be stored (to be merged here directly).
  std::vector<MapId> store_merge_work(const std::vector<MapId>& maps, const SessionStart& start);
  // The merging worker is done with `map`'s row (merged or given up).
  void merge_done(MapId map);
  // The merging worker put a claimed row off (its place is in `target`, a map
  // another replica writes or a session holds): ask for `target`, retry later.
  void merge_put_off(MapId source, MapId target);
  // A mapping session's row (kept while it maps; ended when it finishes or
  // fails; a shutdown leaves it for another replica to adopt). A database
  // error is logged, never thrown.
  void begin_session_work(SessionId id, const StoredMerge& request);
  void end_session_work(SessionId id);

  // One round of each thread's work (the threads run them every lease).
  std::vector<MapId> take_over_maps();
  std::vector<MapId> refresh_others_maps();
  void share_merge_work();

 private:
  void wake_merge_work();
  void take_over_until_stopped();
  void share_merge_work_until_stopped();
  void load_new_sessions(AtlasStore& store, bool rigs_of_live_replicas);
  AtlasStore& store();  // the takeover thread's connection (opened when first needed)
  void swap_in_maps(const std::vector<std::shared_ptr<Map>>& fresh, const std::vector<MapId>& gone);
  void adopt_gone_sessions_work();
  bool hand_over_if_idle(MapId map, std::uint64_t to);
  bool submit_stored_merge(const StoredMerge& merge);

  const ReplicaParts parts_;
  std::map<MapId, std::int64_t> seen_versions_;  // the takeover thread's only
  std::optional<AtlasStore> store_;              // the takeover thread's only

  std::mutex mutex_;  // guards stopped_, merge_work_woken_
  std::condition_variable takeover_wake_, merge_work_wake_;
  bool stopped_ = false, merge_work_woken_ = false;

  std::mutex claimed_mutex_;        // a leaf
  std::set<MapId> claimed_merges_;  // rows this replica's merging worker has

  std::thread takeover_thread_, merge_work_thread_;
};

}  // namespace orbatlas
