#pragma once
// The merge work finished sessions leave in a shared (PostgreSQL) atlas
// (schema/013_shared_merges and 014_merge_claims, docs/scaling.md "Replicas"): one row
// per map to search for a place shared with the atlas's other maps (then
// merged and refined, MapMergeWorker). The replica owning the map claims the
// row (FOR UPDATE SKIP LOCKED) when its merging worker is free, does the work
// and deletes the row. A row nobody claims for a lease (its owner's worker is
// busy, or it runs with --no-merging) is asked for by a free replica, which
// the owner hands the map to (MapOwnership::want, hand_over); so is a map
// another replica's merge found its place in (the row waits meanwhile,
// defer()). A dead replica's rows go with its maps to the replica that takes
// them over; a row claimed by a dead replica waits again.
// A live mapping session has a row of its own (schema/015_session_merge_work): when its
// replica dies or stops before the session finishes, another replica turns it
// into rows of the maps the session's stored keyframes are in
// (adopt_sessions_of_gone_replicas), so its end's work is still done.
//
// Thread-safe: one connection under a mutex.
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "core/common/ids.h"
#include "core/optimization/global_bundle_adjustment.h"
#include "core/server/session_request.h"

namespace orbatlas {

class PgDb;

// What a MergeRequest needs besides its camera (made again from `settings`).
struct StoredMerge {
  MapId map = 0;
  SettingsSource settings;
  KeyframeId first_keyframe = 0;
  std::optional<GlobalBundleAdjustmentOptions::Inertial> inertial;
  bool single_camera = false;
};

// As stored (JSON) and back (DataError on a malformed one).
std::string stored_merge_json(const StoredMerge& merge);
StoredMerge stored_merge_from_json(MapId map, const std::string& text);

class SharedMerges {
 public:
  explicit SharedMerges(std::string location);
  ~SharedMerges();
  SharedMerges(const SharedMerges&) = delete;
  SharedMerges& operator=(const SharedMerges&) = delete;

  void add(const StoredMerge& merge);  // replaces the map's row (waiting again)
  void remove(MapId map);
  std::vector<StoredMerge> of(const std::vector<MapId>& maps);  // the rows of these maps

  // A mapping session of replica `replica` started; its merge work
  // (`request`, whose map is not used) is kept until end_session().
  void begin_session(SessionId session, std::uint64_t replica, const StoredMerge& request);
  // The session finished (its maps' rows added first) or failed.
  void end_session(SessionId session);
  // The sessions of replicas no longer alive (stopped, or their lease passed)
  // that never ended: each becomes a row (its request) for every map its
  // stored keyframes are in, unless that map has one. Returns those maps.
  // One statement: two replicas adopting at once never both take a session.
  std::vector<MapId> adopt_sessions_of_gone_replicas();

  // The oldest waiting row of a map replica `me` owns (unclaimed, or claimed
  // by a replica no longer alive; its retry time passed), now claimed by `me`.
  std::optional<StoredMerge> claim(std::uint64_t me);
  // Puts a claimed row back, not to be claimed before `retry_ns` (unix ns).
  void defer(MapId map, std::int64_t retry_ns);
  // Puts a claimed row back as it was (claimable at once).
  void unclaim(MapId map);
  // True when `map`'s row was put back (defer()) and waits for another map.
  bool put_off(MapId map);
  // The oldest row waiting unclaimed since before `requested_before_ns`, never
  // put back, whose map a live replica other than `me` owns (its owner did not
  // take it: its worker is busy, or it does not merge).
  std::optional<MapId> waiting_elsewhere(std::uint64_t me, std::int64_t requested_before_ns);

 private:
  const std::string location_;
  std::mutex mutex_;  // a leaf; guards db_
  std::unique_ptr<PgDb> db_;
};

}  // namespace orbatlas
