#pragma once
// The server-wide map-merging worker (docs/server.md): when a session finishes,
// its maps are handed over here; one thread looks for a place they share with
// another map of the atlas (place recognition over every map, PlaceScope::
// kOtherMaps), and when one is verified merges the session's map into the other
// (core/loop/map_merge.h), then refines the joined map with a global bundle
// adjustment that stop() interrupts; a map that shares no place with another is
// refined by a global bundle adjustment too. While it works on two maps it holds their
// leases, so no session relocalises into them meanwhile; maps held by live
// sessions are never candidates. Bounded queue: a full queue skips the request
// (logged and counted).
#include <atomic>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>

#include "core/common/queue_worker.h"
#include "core/loop/map_merge.h"
#include "core/loop/place_recognizer.h"
#include "core/map/atlas.h"
#include "core/optimization/global_bundle_adjustment.h"
#include "core/server/map_leases.h"

namespace orbatlas {

// The lease holder name of the worker (never a session id handed out).
inline constexpr SessionId kMergeWorkerLease = kInvalidSessionId - 1;  // no session gets this id

struct MapMergeWorkerOptions {
  std::size_t queue_capacity = 16;
  int worker_nice = 0;                  // the worker thread's nice value (thread_priority.h)
  PlaceRecognitionOptions recognition;  // scope is forced to PlaceScope::kOtherMaps
  MapMergeOptions merge;
  bool global_bundle_adjustment = true;  // after a merge, and (below) on a map not merged
  // A finished session's map that shares no place with another is still refined
  // by one global BA (every constraint the session found, jointly).
  bool refine_unmerged = true;
  GlobalBundleAdjustmentOptions global;
  std::size_t settled_inertial_refinements = 2;  // as LoopCloserOptions'

  // Throws Error naming the first value out of range.
  void check() const;
};

struct MergeRequest {
  MapId map = 0;
  // The camera the map's keyframes were made with (shared: it keeps its owner alive).
  std::shared_ptr<const FrameCamera> cam;
  // Only keyframes with this id or above are searched (ids grow atlas-wide: the
  // keyframes the finished session made), so that a session that worked in a
  // large stored map does not make the worker search all of it again.
  KeyframeId first_keyframe = 0;
  // A visual-inertial session's (its IMU in the body): the global BA of an
  // inertially initialised map keeps the IMU terms of every session's chain
  // (the maps merged are of the same rig). None: visual only.
  std::optional<GlobalBundleAdjustmentOptions::Inertial> inertial;
  // A single camera's session (mono, mono_inertial): its map of free scale (or
  // with an IMU scale not settled yet) is matched and merged as a similarity,
  // taking the target's scale (merges_in_sim3).
  bool single_camera = false;
};

struct MergeRecord {
  MapMergeStats merge;  // source, target, what moved and was fused
  KeyframeId current = 0, matched = 0;
  int matches = 0, verified_keyframes = 0;
  double search_ms = 0.0;              // place recognition until the match
  std::size_t keyframes_searched = 0;  // of the source map
  std::size_t ba_keyframes = 0, ba_inertial_edges = 0;
  double ba_seconds = 0.0;
  bool ba_interrupted = false;
};

struct MapRefinement {
  MapId map = 0;
  std::size_t keyframes = 0, inertial_edges = 0;
  double seconds = 0.0;
  bool interrupted = false;
};

// A long-running server keeps the most recent records only (and counts all).
inline constexpr std::size_t kMergeHistory = 100;

// Appends `item`, dropping the oldest beyond kMergeHistory.
template <typename T>
void push_recent(std::vector<T>& list, T item) {
  if (list.size() >= kMergeHistory)
    list.erase(list.begin(), list.begin() + static_cast<std::ptrdiff_t>(list.size() - kMergeHistory + 1));
  list.push_back(std::move(item));
}

struct MapMergeWorkerStats {
  std::size_t requests = 0, skipped = 0;   // handed in / dropped (queue full, stopped)
  std::vector<MapRefinement> refinements;  // global BAs of maps not merged (the last kMergeHistory)
  std::size_t refinements_total = 0;
  std::size_t maps_searched = 0, keyframes_searched = 0;
  std::vector<MergeRecord> merges;  // the last kMergeHistory
  std::size_t merges_total = 0;
  std::size_t pending = 0;  // queued or in progress
  std::string last_error;
  std::size_t errors = 0;  // requests given up after an error (the worker went on)
};

class MapMergeWorker {
 public:
  // May `source` be merged with `target`? (same camera rig...). Called under
  // the keyframe index's lock: it must not block.
  using MayMerge = std::function<bool(MapId source, MapId target)>;
  // After each merge, on the worker thread (the service stores it).
  using OnMerged = std::function<void(const MergeRecord&)>;

  // `atlas` and `leases` must outlive the worker; the thread starts at once.
  MapMergeWorker(Atlas& atlas, MapLeases& leases, MayMerge may_merge, OnMerged on_merged,
                 MapMergeWorkerOptions options = {});
  ~MapMergeWorker();  // stop()
  MapMergeWorker(const MapMergeWorker&) = delete;
  MapMergeWorker& operator=(const MapMergeWorker&) = delete;

  // Non-blocking; false when the queue is full or the worker stopped.
  bool submit(MergeRequest request);
  // Waits until every submitted request is done.
  void wait_until_idle();
  // Interrupts the search and a running global adjustment, drops what is
  // queued, joins the thread. Idempotent.
  void stop();

  MapMergeWorkerStats stats() const;
  // Called on the worker thread when a request's map has been searched (and
  // merged or refined, or found gone), not when stop() cut it short. Set
  // before the first submit (a shared atlas forgets the map's stored merge work).
  void set_on_done(std::function<void(MapId)> on_done) { on_done_ = std::move(on_done); }
  // A shared atlas: when a request's map found its place in a map this server
  // may not write (`target_writable` false: another replica's), or one a
  // session or the service holds just then, the request ends without a merge
  // and without on_done; `on_put_off(source, target)` is called instead (the
  // service keeps the work for later). Unset (one server): such a request is
  // done without a merge. Set before the first submit.
  void set_put_off(std::function<bool(MapId target)> target_writable,
                   std::function<void(MapId source, MapId target)> on_put_off) {
    target_writable_ = std::move(target_writable);
    on_put_off_ = std::move(on_put_off);
  }

 private:
  void run_one(const MergeRequest& request);  // on the worker thread; leases released after
  // The target a request was put off for (set_put_off); none when it is done.
  std::optional<MapId> process(const MergeRequest& request);
  // One global BA of `map` with the request's camera and IMU (stop() interrupts it).
  GlobalBundleAdjustmentResult refine(Map& map, const MergeRequest& request, double* seconds);

  Atlas& atlas_;
  MapLeases& leases_;
  const MayMerge may_merge_;
  const OnMerged on_merged_;
  std::function<void(MapId)> on_done_;
  std::function<bool(MapId)> target_writable_;
  std::function<void(MapId, MapId)> on_put_off_;
  const MapMergeWorkerOptions options_;

  std::atomic<bool> stopping_{false};  // interrupts a search or global adjustment
  mutable std::mutex mutex_;           // leaf: guards stats_
  MapMergeWorkerStats stats_;          // pending, skipped and errors are filled in by stats()

  // Queue, thread, idle wait and errors (never fatal: a failed request is
  // given up, the server goes on). Last: its thread starts after the above.
  QueueWorker<MergeRequest> worker_;
};

}  // namespace orbatlas
