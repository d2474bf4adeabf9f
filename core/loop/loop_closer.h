#pragma once
// The loop-closing worker (ORB-SLAM's LoopClosing thread) for one session: local
// mapping hands it every processed keyframe through a bounded queue; it runs
// place recognition, corrects verified loops with local mapping paused, and
// starts a global bundle adjustment in a background thread, which a new loop
// interrupts. The adjustment's result is applied to the map (again with local
// mapping paused) together with what was created meanwhile.
// With live merging on, each keyframe is first looked for in the atlas's OTHER
// maps: a verified place there merges the session's active map into that map
// while the session goes on (tracking follows into the joined map), then a
// global bundle adjustment refines the joined map. See docs/loop_closing.md.
#include <atomic>
#include <chrono>
#include <functional>
#include <condition_variable>
#include <map>
#include <set>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "core/common/queue_worker.h"
#include "core/common/sample_summary.h"
#include "core/common/serial_worker.h"
#include "core/common/worker_errors.h"
#include "core/loop/loop_correction.h"
#include "core/loop/map_merge.h"
#include "core/loop/place_recognizer.h"
#include "core/map/atlas.h"
#include "core/loop/mapping_control.h"
#include "core/tracking/frame_camera.h"
#include "core/optimization/global_bundle_adjustment.h"

namespace orbatlas {

struct LiveMerge {
  KeyframeId current = 0, matched = 0;
  TimestampNs current_t_ns = 0;
  int matches = 0;
  int verified_keyframes = 0;
  MapMergeStats merge;
};

struct LoopCloserOptions {
  std::size_t queue_capacity = 32;  // keyframes waiting for place recognition (more are skipped)
  // The nice value of its threads (place recognition when it has its own, the
  // global BA; thread_priority.h); 0 leaves them as created.
  int worker_nice = 0;
  PlaceRecognitionOptions recognition;
  LoopCorrectionOptions correction;
  bool global_bundle_adjustment = true;
  GlobalBundleAdjustmentOptions global;
  // A map that several sessions (streams) map at once gets a global BA each
  // time it has grown by this fraction of its keyframes since its last one
  // (0: never). Sessions that track each other's points close no loop there,
  // so nothing else makes such a map consistent while they run (of four
  // sessions in one map, two ended 1.5-3 times less accurate than alone
  // without it; docs/benchmarks.md). A map of one session is never adjusted so.
  double shared_map_refinement_growth = 0.5;
  std::size_t shared_map_refinement_min_keyframes = 20;
  // When a stream ends in such a map (refine_at_stream_end) and the map grew by
  // this fraction since its last global BA, one more runs at once, so that the
  // ending session's keyframes are adjusted with the map before it reads its
  // trajectory (0: never). Between two refinements of the rule above a shared
  // map grows by up to half, unadjusted.
  double stream_end_refinement_growth = 0.1;
  // A single camera's inertial map (monocular, initialised) gets that global BA
  // at a session's end when one session mapped it too: its scale comes from
  // the IMU alone (SlamSystemOptions::final_ba_for_imu_scale sets it).
  bool stream_end_imu_scale = false;
  // The sessions' maps have no metric scale until an IMU gives them one
  // (monocular): loops and merges are then similarities (Sim(3)).
  bool monocular = false;
  // A monocular map made metric by its IMU keeps a scale several per cent off
  // until this many inertial refinements (ORB-SLAM3 merges an inertial map
  // only after its second, "BA2"): until then it is merged in Sim(3), taking
  // the target's scale, as a map of free scale is.
  std::size_t settled_inertial_refinements = 2;

  // Live map merging: each keyframe is also searched for in the other maps of
  // the atlas (those LoopCloserWiring::may_merge_into accepts).
  bool live_merging = false;
  PlaceRecognitionOptions merge_recognition;  // scope and may_use_map are set by the closer
  MapMergeOptions merge;

  // Throws Error naming the first value out of range.
  void check() const;
};

// How a loop closer is connected to what runs around it (data stays in the options).
struct LoopCloserWiring {
  // When set, place recognition and loop correction run on this thread shared
  // with other sessions (the server: one for all), not on a thread of the
  // closer's own; its bounded queue then decides what is skipped.
  std::shared_ptr<SerialWorker> shared_worker;
  // Live merging: only into maps this accepts (empty: all). Before a merge of
  // `source` into `target`, `hold_map` must agree (the server: the sessions in
  // `source` take `target`'s lease; empty: yes); `on_merged` is told afterwards
  // (on the worker thread).
  std::function<bool(MapId)> may_merge_into;
  std::function<bool(MapId source, MapId target)> hold_map;
  std::function<void(const LiveMerge&)> on_merged;
};

struct ClosedLoop {
  KeyframeId current = 0, matched = 0;
  TimestampNs current_t_ns = 0, matched_t_ns = 0;
  Pose3 T_cur_m;       // estimated relative camera pose (current <- matched), in the matched units
  double scale = 1.0;  // current units per matched unit (1 unless the map's scale is free)
  int matches = 0;
  LoopCorrectionStats correction;
};

// Why a global BA ran: after a loop correction, after a live merge, or for a
// map several sessions map at once (LoopCloserOptions::shared_map_refinement_growth),
// or for such a map when a session ends in it (stream_end_refinement_growth).
// kInertial: a map's full visual-inertial BA after its inertial
// initialisation or a refinement (Map::request_inertial_adjustment).
enum class GlobalAdjustmentCause { kLoop, kMerge, kSharedMap, kStreamEnd, kInertial };
const char* to_string(GlobalAdjustmentCause cause);

struct GlobalAdjustmentRun {
  GlobalAdjustmentCause cause = GlobalAdjustmentCause::kLoop;
  std::size_t keyframes = 0, points = 0;
  std::size_t inertial_edges = 0;  // IMU terms of an inertial map's chain (0: visual only)
  double seconds = 0.0;
  bool interrupted = false;  // a new loop stopped it; its result was dropped
};

struct LoopClosingStats {
  std::size_t keyframes = 0;           // run through place recognition
  std::size_t keyframes_skipped = 0;   // the queue was full
  std::size_t hypotheses = 0;          // geometric hypotheses that passed the guided search
  SampleSummary place_recognition_ms;  // per keyframe (bounded)
  std::vector<ClosedLoop> loops;
  std::vector<LiveMerge> merges;  // live merges of the active map into another
  SampleSummary merge_search_ms;  // per keyframe, when live merging is on
  std::vector<GlobalAdjustmentRun> global_adjustments;
  WorkerErrorCounts errors;  // keyframes / adjustments given up after an error
};

class LoopCloser {
 public:
  // `atlas`, the camera and `mapping` must outlive the loop closer. Local
  // mapping hands it every keyframe it has processed (insert()). The thread
  // starts at once. Edits of a map (loop correction, merge, applying a global
  // adjustment) pause the map's mapping and hold the atlas's maps exclusive,
  // so tracking (which holds them shared per frame) never sees a half-moved map.
  LoopCloser(Atlas& atlas, FrameCamera cam, MappingControl& mapping, LoopCloserOptions options = {},
             LoopCloserWiring wiring = {});
  ~LoopCloser();  // finish()
  LoopCloser(const LoopCloser&) = delete;
  LoopCloser& operator=(const LoopCloser&) = delete;

  // Non-blocking (called on a mapper thread): a full queue skips the keyframe.
  // `stream`: the trajectory the keyframe belongs to (a session); place
  // recognition verifies a hypothesis with later keyframes of the same stream.
  void insert(const std::shared_ptr<KeyFrame>& keyframe, std::uint64_t stream = 0);
  // The stream has ended: its recognition state goes (any thread).
  void forget_stream(std::uint64_t stream);
  // The stream has ended in `map`, its keyframes processed by local mapping
  // (any thread but the worker's). When two or more streams mapped the map
  // since its last global BA and it grew by stream_end_refinement_growth since,
  // a global BA of the map starts now; when one of the map runs, that one is
  // taken. Waits at most `max_wait` for it to be applied. True when it was, or
  // none was due; false when the wait ran out (the adjustment goes on and is
  // applied later), the request found the queue full, or the adjustment was
  // interrupted or failed.
  bool refine_at_stream_end(MapId map, std::chrono::milliseconds max_wait);
  // Waits until every inserted keyframe is processed and no global adjustment runs.
  void wait_until_idle();
  // Call after local mapping has finished: processes what is queued, waits for a
  // running global adjustment and merges it, stops the threads. Idempotent;
  // rethrows a fatal error (a keyframe that failed alone is only counted).
  void finish();

  LoopClosingStats stats() const;
  WorkerErrorCounts errors() const { return worker_.errors(); }  // cheap

 private:
  // A refine_at_stream_end() caller's wait (fields under global_mutex_).
  struct StreamEndWait {
    MapId map = kInvalidMapId;
    bool done = false;     // nothing more will happen for it
    bool applied = false;  // an adjustment of the map was applied, or none was due
  };
  // A keyframe, or (keyframe null) a stream's end in a map.
  struct Item {
    std::shared_ptr<KeyFrame> keyframe;
    std::uint64_t stream = 0;
    std::shared_ptr<StreamEndWait> stream_end;
  };
  // Place recognition of one stream (its pending hypotheses).
  struct Recognizers {
    PlaceRecognizer loops;
    std::unique_ptr<PlaceRecognizer> merges;  // live merging only
  };
  Recognizers& recognizers(std::uint64_t stream);  // worker thread
  void process(const Item& item);
  void close_loop(const PlaceMatch& loop);
  // True when the active map was merged into the match's map.
  bool merge_live(const PlaceMatch& match);
  void stop_global_adjustment();
  // `wait` (may be null) is told when the adjustment has ended.
  void start_global_adjustment(MapId map, GlobalAdjustmentCause cause, std::shared_ptr<StreamEndWait> wait = nullptr);
  // Worker thread: the full visual-inertial BA the keyframe's map asked for,
  // started; false when it asked for none.
  bool adjust_inertial_map(const Item& item);
  // Worker thread: the stream-end request of refine_at_stream_end().
  void handle_stream_end(const std::shared_ptr<StreamEndWait>& wait);
  // Worker thread: a map is due a refinement when streams.size() >= 2 (at a
  // stream's end also a single camera's inertial map, stream_end_imu_scale)
  // and it has at least min_keyframes and (1 + growth) times its keyframes then.
  bool refinement_due(MapId map, double growth, bool at_stream_end);
  // Worker thread: drops since_global_'s entries of maps merged away.
  void forget_merged_maps();
  // A global BA of the keyframe's map when several streams map it and it grew
  // enough since its last one (shared_map_refinement_growth); none while one runs.
  void refine_shared_map(const Item& item);

  Atlas& atlas_;
  const FrameCamera cam_;
  MappingControl& mapping_;
  const LoopCloserOptions options_;
  const LoopCloserWiring wiring_;
  std::map<std::uint64_t, Recognizers> recognizers_;  // worker thread only
  // Worker thread only: per map, its keyframes at its last global BA and the
  // streams that inserted keyframes since.
  struct SinceGlobalAdjustment {
    std::size_t keyframes = 0;
    std::set<std::uint64_t> streams;
  };
  std::map<MapId, SinceGlobalAdjustment> since_global_;
  std::mutex forgotten_mutex_;            // leaf: guards forgotten_
  std::vector<std::uint64_t> forgotten_;  // streams to drop on the worker thread

  std::mutex global_mutex_;  // leaf: guards what follows, and StreamEndWait's fields
  std::condition_variable global_cv_;
  bool global_running_ = false;
  MapId global_map_ = kInvalidMapId;                          // the running adjustment's
  std::vector<std::shared_ptr<StreamEndWait>> global_waits_;  // told when it ends

  // One correction at a time touches the map with local mapping paused.
  std::mutex correction_mutex_;
  std::atomic<bool> stop_global_{false};
  std::thread global_thread_;  // owned by the worker thread (started / joined there and in finish)

  mutable std::mutex stats_mutex_;
  LoopClosingStats stats_;

  // Queue (or the shared thread), idle wait and errors (fatal after 20
  // failures in a row). Last: its thread starts after everything above exists.
  QueueWorker<Item> worker_;
};

}  // namespace orbatlas
