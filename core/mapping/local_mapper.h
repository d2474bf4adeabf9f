#pragma once
// Local mapping (ORB-SLAM's LocalMapping) of one map in its own thread, fed by
// tracking through a bounded queue (every session tracking in the map feeds the
// same mapper: core/slam/mapping_workers.h). Per keyframe: complete the new keyframe (point
// normals and descriptors, covisibility, spanning-tree parent), cull recent
// points that tracking does not confirm, triangulate new points with the
// covisible keyframes, fuse duplicates with the neighbours, run local bundle
// adjustment, and cull redundant keyframes. See docs/mapping.md.
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <vector>

#include "core/common/queue_worker.h"
#include "core/common/sample_summary.h"
#include "core/common/worker_errors.h"
#include "core/map/atlas.h"
#include "core/map/keyframe_index.h"
#include "core/mapping/inertial_consistency.h"
#include "core/mapping/imu_scale_filter.h"
#include "core/mapping/inertial_initializer.h"
#include "core/mapping/keyframe_culling.h"
#include "core/optimization/global_bundle_adjustment.h"
#include "core/optimization/local_bundle_adjustment.h"
#include "core/tracking/frame_camera.h"

namespace orbatlas {

struct LocalMapperOptions {
  std::size_t queue_capacity = 8;
  // The mapping thread's nice value (thread_priority.h): the map server runs
  // background work below its sessions' tracking; 0 leaves it as created.
  int worker_nice = 0;
  std::size_t triangulation_neighbours = 10;  // best covisibles (ORB-SLAM: 10 for stereo)
  std::size_t fusion_neighbours = 10;
  std::size_t fusion_second_neighbours = 5;
  float fusion_radius = 3.0f;
  KeyframeCullingOptions culling;
  LocalBundleAdjustmentOptions bundle_adjustment;  // origin and level_sigma2 are filled in
  bool run_bundle_adjustment = true;
  bool run_culling = true;
  InertialInitializationOptions inertial;  // visual-inertial sessions: initialise each map's IMU state
  // Visual-inertial sessions, once the map is initialised: local BA with the
  // last keyframes of the inertial chain, their velocities and biases.
  bool inertial_bundle_adjustment = true;
  std::size_t inertial_window_keyframes = 10;
  // Covisible keyframes optimised (pose only) beside the chain's in a
  // visual-inertial local BA; the others observing its points are fixed.
  std::size_t inertial_covisible_keyframes = 1000;
  // With imu_scale_sigma > 0 the IMU's scale factors (ImuScaleCorrection) are
  // estimated with each visual-inertial local BA, under a prior of that sigma
  // per axis about the map's estimate, and fused into the map's estimate by
  // what each window told of them (imu_scale_filter.h, the same sigma its
  // prior about none). 0: the factors are taken as they are.
  double imu_scale_sigma = 0.0;
  // After a map's inertial initialisation and each refinement: a full
  // visual-inertial BA (every keyframe and point, the chain's IMU states;
  // ORB-SLAM3's FullInertialBA); iterations 0: none.
  int full_inertial_ba_iterations = 20;
  // The full BA is asked of the loop closer's background adjustment
  // (Map::request_inertial_adjustment) instead of run here: local mapping goes
  // on meanwhile (a full BA over 50-120 keyframes takes seconds, while the rig
  // moves on into places without points). Set by MappingWorkers when its loop
  // closer runs global BAs.
  bool defer_full_inertial_ba = false;
  // A map whose IMU disagrees with its vision goes visual-only and is
  // initialised again later (inertial_consistency.h).
  InertialConsistencyOptions inertial_consistency;

  // Throws Error naming the first value out of range.
  void check() const;
};

// Figures of a run (copies; safe to read while the mapper runs).
struct LocalMapperStats {
  std::size_t keyframes = 0;  // processed
  // Bounded (a long-running server keeps the same memory per figure).
  SampleSummary keyframe_ms;  // whole processing per keyframe
  SampleSummary bundle_adjustment_ms;
  SampleSummary bundle_adjustment_window;  // keyframes optimised per local BA
  SampleSummary bundle_adjustment_fixed;   // keyframes held fixed per local BA (its border)
  SampleSummary culling_scan_ms;           // per keyframe (all candidates), when the scan ran
  SampleSummary culling_incremental_ms;    // per keyframe, when the incremental read ran
  std::size_t culling_candidates = 0;
  std::size_t culling_disagreements = 0;
  std::size_t culled_keyframes = 0;
  // FNV-1a of the culled keyframes' ids in order: two runs culled the same
  // keyframes in the same order exactly when count and digest agree.
  std::uint64_t culled_keyframes_digest = 14695981039346656037ULL;
  std::size_t points_triangulated = 0, points_fused = 0, observations_fused = 0, recent_points_culled = 0;
  std::size_t bundle_adjustments_interrupted = 0;
  std::size_t inertial_bundle_adjustments = 0;  // local BAs with inertial edges
  SampleSummary inertial_chi2_median;           // each of those BAs' median inertial chi2 (9 dof) after it
  std::size_t inertial_refinements = 0;         // of maps' inertial initialisation
  // Maps whose inertial state was dropped because their IMU disagreed with
  // vision (inertial_consistency.h), and of those the ones given up for good.
  std::size_t inertial_resets = 0, inertial_given_up = 0;
  std::size_t full_inertial_bundle_adjustments = 0;
  SampleSummary full_inertial_ba_ms;
  WorkerErrorCounts errors;  // keyframes whose processing failed (given up, the mapper went on)
};

// Where mappers write their figures: one board may collect those of several
// mappers (the maps of a session or of a server, in order of processing).
struct LocalMapperStatsBoard {
  mutable std::mutex mutex;
  LocalMapperStats stats;  // errors: filled in by LocalMapper::stats()
};

class LocalMapper final {
 public:
  // `atlas`, `cam.camera` and `index` (may be null) must outlive the mapper. The
  // thread starts at once. Processed keyframes are added to `index`, culled ones
  // erased from it. Figures go to `board` (null: one of its own).
  LocalMapper(Atlas& atlas, FrameCamera cam, LocalMapperOptions options, KeyframeIndex* index = nullptr,
              std::shared_ptr<LocalMapperStatsBoard> board = nullptr);
  ~LocalMapper();  // finish()
  LocalMapper(const LocalMapper&) = delete;
  LocalMapper& operator=(const LocalMapper&) = delete;

  // What tracking asks (KeyframeSink, for the mapper's map).
  //
  // Several sessions may feed one mapper; each is a `source` (the session's
  // keyframe stream; 0 when there is one). ORB-SLAM's rules that trade a
  // keyframe's work for the next one's (insert a keyframe when mapping is
  // idle, skip a keyframe's local BA and cut its triangulation short when
  // another waits, stop the running BA when a keyframe comes) are kept per
  // source: one session's keyframe neither makes the mapper busy for another
  // session's keyframe decision nor cuts another session's keyframes' BA short
  // (measured: four recordings in one map had 56 local BAs stopped by another
  // session's keyframe; per source, none. docs/mapping.md).
  // The whole queue still bounds the work: beyond half of it, every keyframe
  // is processed in the short way, whoever it is from.
  bool idle() const { return worker_.idle(); }
  // No keyframe of `source` queued or being processed.
  bool idle(std::uint64_t source) const;
  std::size_t queued() const { return worker_.queued(); }
  // Blocks while the queue is full; false (not taken) once finishing.
  bool insert(std::shared_ptr<KeyFrame> keyframe, std::uint64_t source = 0);
  // Stops the running local BA early when it is one of `source`'s keyframes.
  void interrupt_optimization(std::uint64_t source = 0);
  // Waits, at most `at_most`, until every keyframe of `source` handed in has
  // been adjusted (its local BA and culling done, or skipped; the inertial
  // work after them is not waited for). True when they have.
  bool wait_until_adjusted(std::uint64_t source, std::chrono::milliseconds at_most) const;
  bool accepting() const { return !worker_.pause_requested(); }

  // Called on the mapper thread with every keyframe it has processed (loop
  // detection). Must not block: hand the keyframe to a queue with try_push.
  // Set before the first insert.
  void set_processed_listener(std::function<void(const std::shared_ptr<KeyFrame>&)> listener);

  // For a loop correction: tracking stops making keyframes, what is queued is
  // processed, and the mapper then waits between keyframes until resume(). While
  // paused nothing in the atlas is edited by this mapper. Returns once paused.
  void pause() { worker_.pause(); }
  void resume() { worker_.resume(); }

  void wait_until_idle() const { worker_.wait_until_idle(); }
  // Processes what is queued, then stops the thread (idempotent). Rethrows a
  // fatal error (WorkerErrors: too many keyframes failed in a row); a keyframe
  // that failed alone is counted in stats().errors and logged.
  void finish() { worker_.finish(); }

  LocalMapperStats stats() const;
  WorkerErrorCounts errors() const { return worker_.errors(); }  // cheap

 private:
  struct RecentPoint {
    std::weak_ptr<MapPoint> point;
    std::size_t created_at = 0;  // keyframe sequence number
  };

  struct Item {
    std::shared_ptr<KeyFrame> keyframe;
    std::uint64_t source = 0;
  };
  void run_one(Item& item);  // on the worker thread
  void process(const std::shared_ptr<KeyFrame>& keyframe, std::uint64_t source);
  // A later keyframe of `source` waits, or the queue is half full: this
  // keyframe's optional work (the rest of its triangulation, fusion, local BA
  // and culling) is left to the next one.
  bool hurry(std::uint64_t source) const;
  void complete_keyframe(const std::shared_ptr<KeyFrame>& keyframe);
  void cull_recent_points(Map& map);
  void triangulate(Map& map, const std::shared_ptr<KeyFrame>& keyframe, std::uint64_t source);
  void fuse_with_neighbours(Map& map, const std::shared_ptr<KeyFrame>& keyframe);
  // After the map's inertial state was set (initialised or refined) at `keyframe`.
  GlobalBundleAdjustmentResult full_inertial_ba(Map& map, const std::shared_ptr<KeyFrame>& keyframe,
                                                const Map::InertialState& state);

  Atlas& atlas_;
  KeyframeIndex* const index_;  // not owned, may be null
  const FrameCamera cam_;
  const LocalMapperOptions options_;

  std::atomic<bool> abort_ba_{false};
  // Keyframes handed in and not yet processed, and those not yet adjusted,
  // per source (leaf lock).
  mutable std::mutex pending_mutex_;
  mutable std::condition_variable adjusted_cv_;
  std::map<std::uint64_t, std::size_t> pending_;
  std::map<std::uint64_t, std::size_t> unadjusted_;
  void handed_in(std::uint64_t source);
  void adjusted(std::uint64_t source);   // once per keyframe handed in
  void processed(std::uint64_t source);  // once per keyframe handed in, after adjusted()
  std::atomic<std::uint64_t> processing_source_{0};
  std::function<void(const std::shared_ptr<KeyFrame>&)> processed_listener_;

  // Mapper-thread state.
  // The keyframe local BA and culling keep fixed in each map (its spanning-tree root).
  static KeyframeId spanning_tree_root(const Map& map, const KeyFrame& keyframe);
  std::map<MapId, KeyframeId> origins_;
  InertialConsistency consistency_{options_.inertial_consistency};
  ImuScaleFilter scale_filter_{
      ImuScaleFilterOptions{.prior_sigma = options_.imu_scale_sigma > 0.0 ? options_.imu_scale_sigma : 0.01,
                            .overlap = static_cast<double>(options_.inertial_window_keyframes)}};
  std::vector<RecentPoint> recent_;
  std::size_t sequence_ = 0;
  bool counted_adjusted_ = false;  // the keyframe in processing has been counted adjusted

  const std::shared_ptr<LocalMapperStatsBoard> board_;

  // Queue, thread, idle wait, pause and errors (fatal after 20 failed keyframes
  // in a row). Last: its thread starts after everything above exists.
  QueueWorker<Item> worker_;
};

}  // namespace orbatlas
