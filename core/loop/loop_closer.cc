#include "core/loop/loop_closer.h"

#include <chrono>

#include "core/common/error.h"
#include "core/common/stopwatch.h"
#include "core/common/log.h"
#include "core/loop/global_adjustment_merge.h"

namespace orbatlas {
namespace {

// Pauses local mapping for the scope (resumes on every exit path).
class MappingPause {
 public:
  explicit MappingPause(LocalMapper& mapper) : mapper_(mapper) { mapper_.pause(); }
  ~MappingPause() { mapper_.resume(); }
  MappingPause(const MappingPause&) = delete;
  MappingPause& operator=(const MappingPause&) = delete;

 private:
  LocalMapper& mapper_;
};

}  // namespace

LoopCloser::LoopCloser(Atlas& atlas, FrameCamera cam, LocalMapper& mapper, LoopCloserOptions options)
    : atlas_(atlas),
      cam_(std::move(cam)),
      mapper_(mapper),
      options_(std::move(options)),
      recognizer_(atlas.keyframe_index(), cam_, options_.recognition),
      queue_(options_.queue_capacity) {
  if (options_.live_merging) {
    PlaceRecognitionOptions merging = options_.merge_recognition;
    merging.scope = PlaceScope::kOtherMaps;
    merging.may_use_map = options_.may_merge_into;
    merge_recognizer_ = std::make_unique<PlaceRecognizer>(atlas.keyframe_index(), cam_, merging);
  }
  mapper_.set_processed_listener([this](const std::shared_ptr<KeyFrame>& kf) { insert(kf); });
  if (!options_.shared_worker) thread_ = std::thread([this] { run(); });
}

LoopCloser::~LoopCloser() {
  try {
    finish();
  } catch (const std::exception& e) {
    log_warn(std::string("loop closing stopped with an error: ") + e.what());
  }
}

void LoopCloser::insert(const std::shared_ptr<KeyFrame>& keyframe) {
  {
    std::lock_guard lock(state_mutex_);
    if (closed_) return;
    ++in_flight_;
  }
  const bool queued = options_.shared_worker ? options_.shared_worker->try_post([this, keyframe] { run_one(keyframe); })
                                             : queue_.try_push(keyframe);
  if (!queued) {
    std::lock_guard lock(state_mutex_);
    --in_flight_;
    idle_cv_.notify_all();
    std::lock_guard stats_lock(stats_mutex_);
    ++stats_.keyframes_skipped;
  }
}

void LoopCloser::wait_until_idle() {
  std::unique_lock lock(state_mutex_);
  idle_cv_.wait(lock, [&] { return in_flight_ == 0 && !global_running_; });
  if (error_) std::rethrow_exception(error_);
}

void LoopCloser::finish() {
  queue_.close();
  if (thread_.joinable()) thread_.join();
  {
    // On a shared worker: wait for this closer's keyframes still queued there
    // (the worker drains its queue even when stopping).
    std::unique_lock lock(state_mutex_);
    closed_ = true;
    idle_cv_.wait(lock, [&] { return in_flight_ == 0; });
  }
  if (global_thread_.joinable()) global_thread_.join();  // let it finish and merge
  std::lock_guard lock(state_mutex_);
  if (error_) std::rethrow_exception(std::exchange(error_, nullptr));
}

LoopClosingStats LoopCloser::stats() const {
  LoopClosingStats out;
  {
    std::lock_guard lock(stats_mutex_);
    out = stats_;
  }
  out.errors = errors_.counts();
  return out;
}

void LoopCloser::record_error(const std::string& unit) {
  if (!errors_.record(unit, std::current_exception())) return;
  std::lock_guard lock(state_mutex_);
  if (!error_) error_ = errors_.fatal_error();
}

void LoopCloser::run() {
  while (auto keyframe = queue_.pop()) run_one(*keyframe);
}

void LoopCloser::run_one(const std::shared_ptr<KeyFrame>& keyframe) {
  try {
    process(keyframe);
    errors_.succeeded();
  } catch (...) {
    // Given up for this keyframe: a correction or merge that failed half-way
    // leaves each keyframe and point as its last complete edit left it.
    record_error("keyframe " + std::to_string(keyframe->id()));
  }
  std::lock_guard lock(state_mutex_);
  --in_flight_;
  idle_cv_.notify_all();
}

std::unique_lock<std::mutex> LoopCloser::pause_tracking() {
  if (!options_.tracking_mutex) return {};
  return std::unique_lock(*options_.tracking_mutex);
}

void LoopCloser::process(const std::shared_ptr<KeyFrame>& keyframe) {
  if (merge_recognizer_) {
    // ORB-SLAM3 looks for a merge first: a keyframe that joins another map is
    // not also taken as a loop.
    const auto start = std::chrono::steady_clock::now();
    const PlaceRecognitionStep step = merge_recognizer_->process(keyframe);
    {
      std::lock_guard lock(stats_mutex_);
      stats_.merge_search_ms.add(ms_since(start));
    }
    if (step.match && !step.match->same_map() && merge_live(*step.match)) return;
  }
  const auto start = std::chrono::steady_clock::now();
  const PlaceRecognitionStep step = recognizer_.process(keyframe);
  {
    std::lock_guard lock(stats_mutex_);
    ++stats_.keyframes;
    stats_.place_recognition_ms.add(ms_since(start));
    if (step.hypothesis) ++stats_.hypotheses;
  }
  if (step.match && step.match->same_map()) close_loop(*step.match);
}

void LoopCloser::close_loop(const PlaceMatch& loop) {
  stop_global_adjustment();
  const auto map = atlas_.map(loop.current->map_id());
  if (!map) return;
  LoopCorrectionStats correction;
  {
    std::lock_guard lock(correction_mutex_);
    MappingPause pause(mapper_);
    const auto tracking = pause_tracking();
    correction = correct_loop(*map, loop, cam_, options_.correction);
  }
  log_info("loop closed: keyframe " + std::to_string(loop.current->id()) + " with " +
           std::to_string(loop.matched->id()) + " (" + std::to_string(loop.matches) + " matches), corrected by " +
           std::to_string(correction.correction_m) + " m in " + std::to_string(correction.total_ms) + " ms");
  {
    std::lock_guard lock(stats_mutex_);
    ClosedLoop closed;
    closed.current = loop.current->id();
    closed.matched = loop.matched->id();
    closed.current_t_ns = loop.current->timestamp_ns();
    closed.matched_t_ns = loop.matched->timestamp_ns();
    closed.T_cur_m = loop.T_cur_m;
    closed.matches = loop.matches;
    closed.correction = correction;
    stats_.loops.push_back(closed);
  }
  if (options_.global_bundle_adjustment) start_global_adjustment(map->id());
}

bool LoopCloser::merge_live(const PlaceMatch& match) {
  const MapId source = match.current->map_id();
  const MapId target = match.matched->map_id();
  if (source == target || !atlas_.map(source) || !atlas_.map(target)) return false;
  if (options_.hold_map && !options_.hold_map(target)) {
    log_info("live merge: map " + std::to_string(target) + " was taken by another session meanwhile; not merged");
    return false;
  }
  stop_global_adjustment();  // it works on the source map, which is about to go
  MapMergeStats merged;
  {
    std::lock_guard lock(correction_mutex_);
    MappingPause pause(mapper_);
    const auto tracking = pause_tracking();
    merged = merge_maps(atlas_, match, cam_, options_.merge);
  }
  log_info("live merge: map " + std::to_string(source) + " merged into map " + std::to_string(target) +
           " at keyframe " + std::to_string(match.current->id()) + " ~ " + std::to_string(match.matched->id()) + " (" +
           std::to_string(match.matches) + " matches, " + std::to_string(merged.keyframes_moved) +
           " keyframes moved, " + std::to_string(merged.points_merged) + " points fused, " + std::to_string(merged.ms) +
           " ms)");
  LiveMerge record;
  record.current = match.current->id();
  record.matched = match.matched->id();
  record.current_t_ns = match.current->timestamp_ns();
  record.matches = match.matches;
  record.verified_keyframes = match.verified_keyframes;
  record.merge = merged;
  {
    std::lock_guard lock(stats_mutex_);
    stats_.merges.push_back(record);
  }
  if (options_.on_merged) options_.on_merged(record);
  if (options_.global_bundle_adjustment) start_global_adjustment(target);
  return true;
}

void LoopCloser::stop_global_adjustment() {
  if (!global_thread_.joinable()) return;
  stop_global_.store(true);
  global_thread_.join();
  stop_global_.store(false);
}

void LoopCloser::start_global_adjustment(MapId map_id) {
  {
    std::lock_guard lock(state_mutex_);
    global_running_ = true;
  }
  global_thread_ = std::thread([this, map_id] {
    try {
      const auto map = atlas_.map(map_id);
      if (map) {
        const auto start = std::chrono::steady_clock::now();
        const GlobalBundleAdjustmentResult result =
            global_bundle_adjustment(*map, *cam_.camera, cam_.bf, options_.global, &stop_global_);
        if (!result.stopped) {
          std::lock_guard lock(correction_mutex_);
          MappingPause pause(mapper_);
          const auto tracking = pause_tracking();
          merge_global_adjustment(*map, result, cam_.pyramid);
        }
        GlobalAdjustmentRun run{result.keyframes, result.points, ms_since(start) * 1e-3, result.stopped};
        log_info("global bundle adjustment: " + std::to_string(run.keyframes) + " keyframes, " +
                 std::to_string(run.seconds) + " s" + (run.interrupted ? " (interrupted)" : ""));
        std::lock_guard lock(stats_mutex_);
        stats_.global_adjustments.push_back(run);
      }
    } catch (...) {
      record_error("global bundle adjustment of map " + std::to_string(map_id));
    }
    std::lock_guard lock(state_mutex_);
    global_running_ = false;
    idle_cv_.notify_all();
  });
}

}  // namespace orbatlas
