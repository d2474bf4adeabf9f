#include "core/common/thread_name.h"
#include "core/common/thread_priority.h"
#include "core/loop/loop_closer.h"

#include <chrono>
#include <cmath>

#include "core/common/error.h"
#include "core/common/stopwatch.h"
#include "core/common/log.h"
#include "core/optimization/apply_global_adjustment.h"

namespace orbatlas {
namespace {

// Pauses the local mapping of one or two maps for the scope (resumes on every
// exit path). Two maps are paused in id order.
class MappingPause {
 public:
  MappingPause(MappingControl& mapping, MapId a, MapId b = kInvalidMapId) : mapping_(mapping) {
    if (b != kInvalidMapId && b < a) std::swap(a, b);
    for (const MapId map : {a, b}) {
      if (map == kInvalidMapId || (count_ > 0 && maps_[0] == map)) continue;
      mapping_.pause(map);
      maps_[count_++] = map;
    }
  }
  ~MappingPause() {
    while (count_ > 0) mapping_.resume(maps_[--count_]);
  }
  MappingPause(const MappingPause&) = delete;
  MappingPause& operator=(const MappingPause&) = delete;

 private:
  MappingControl& mapping_;
  MapId maps_[2] = {kInvalidMapId, kInvalidMapId};
  int count_ = 0;
};

}  // namespace

const char* to_string(GlobalAdjustmentCause cause) {
  switch (cause) {
    case GlobalAdjustmentCause::kLoop:
      return "loop";
    case GlobalAdjustmentCause::kMerge:
      return "merge";
    case GlobalAdjustmentCause::kSharedMap:
      return "shared_map";
    case GlobalAdjustmentCause::kStreamEnd:
      return "stream_end";
    case GlobalAdjustmentCause::kInertial:
      return "inertial";
  }
  return "?";
}

void LoopCloserOptions::check() const {
  ORBATLAS_CHECK(queue_capacity > 0, "loop closing: queue_capacity must be > 0, not " << queue_capacity);
  ORBATLAS_CHECK(worker_nice >= 0 && worker_nice <= 19,
                 "loop closing: worker_nice must be in 0..19, not " << worker_nice);
  ORBATLAS_CHECK(std::isfinite(shared_map_refinement_growth) && shared_map_refinement_growth >= 0.0,
                 "loop closing: shared_map_refinement_growth must be >= 0, not " << shared_map_refinement_growth);
  ORBATLAS_CHECK(std::isfinite(stream_end_refinement_growth) && stream_end_refinement_growth >= 0.0,
                 "loop closing: stream_end_refinement_growth must be >= 0, not " << stream_end_refinement_growth);
  recognition.check();
  correction.check();
  global.check();
  merge_recognition.check();
  merge.check();
}

LoopCloser::LoopCloser(Atlas& atlas, FrameCamera cam, MappingControl& mapping, LoopCloserOptions options,
                       LoopCloserWiring wiring)
    : atlas_(atlas),
      cam_(std::move(cam)),
      mapping_(mapping),
      options_((options.check(), std::move(options))),
      wiring_(std::move(wiring)),
      worker_(
          QueueWorkerOptions{.name = "loop closing",
                             .capacity = options_.queue_capacity,
                             .shared = wiring_.shared_worker,
                             .nice = options_.worker_nice},
          [this](Item& item) { process(item); },
          [](const Item& item) {
            return item.keyframe ? "keyframe " + std::to_string(item.keyframe->id())
                                 : "the end of a session in map " + std::to_string(item.stream_end->map);
          }) {}

LoopCloser::Recognizers& LoopCloser::recognizers(std::uint64_t stream) {
  {
    std::lock_guard lock(forgotten_mutex_);
    for (const std::uint64_t gone : forgotten_) recognizers_.erase(gone);
    forgotten_.clear();
  }
  auto it = recognizers_.find(stream);
  if (it == recognizers_.end()) {
    std::unique_ptr<PlaceRecognizer> merges;
    if (options_.live_merging) {
      PlaceRecognitionOptions merging = options_.merge_recognition;
      merging.scope = PlaceScope::kOtherMaps;
      merging.may_use_map = wiring_.may_merge_into;
      merges = std::make_unique<PlaceRecognizer>(atlas_.keyframe_index(), cam_, merging);
    }
    it = recognizers_
             .emplace(stream, Recognizers{PlaceRecognizer(atlas_.keyframe_index(), cam_, options_.recognition),
                                          std::move(merges)})
             .first;
  }
  return it->second;
}

void LoopCloser::forget_stream(std::uint64_t stream) {
  std::lock_guard lock(forgotten_mutex_);
  forgotten_.push_back(stream);
}

LoopCloser::~LoopCloser() {
  try {
    finish();
  } catch (const std::exception& e) {
    log_warn(std::string("loop closing stopped with an error: ") + e.what());
  }
}

void LoopCloser::insert(const std::shared_ptr<KeyFrame>& keyframe, std::uint64_t stream) {
  if (worker_.try_push(Item{keyframe, stream, nullptr})) return;
  std::lock_guard stats_lock(stats_mutex_);
  ++stats_.keyframes_skipped;
}

bool LoopCloser::refine_at_stream_end(MapId map, std::chrono::milliseconds max_wait) {
  auto wait = std::make_shared<StreamEndWait>();
  wait->map = map;
  if (!worker_.try_push(Item{nullptr, 0, wait})) return false;
  std::unique_lock lock(global_mutex_);
  if (!global_cv_.wait_for(lock, max_wait, [&] { return wait->done; })) return false;
  return wait->applied;
}

void LoopCloser::handle_stream_end(const std::shared_ptr<StreamEndWait>& wait) {
  const auto tell = [&](bool applied) {
    std::lock_guard lock(global_mutex_);
    wait->done = true;
    wait->applied = applied;
    global_cv_.notify_all();
  };
  try {
    {
      std::lock_guard lock(global_mutex_);
      if (global_running_ && global_map_ == wait->map) {
        global_waits_.push_back(wait);  // the running one: told when it ends
        return;
      }
    }
    forget_merged_maps();
    const bool due = options_.global_bundle_adjustment && options_.stream_end_refinement_growth > 0.0 &&
                     refinement_due(wait->map, options_.stream_end_refinement_growth, true);
    if (!due) return tell(true);
    {
      std::lock_guard lock(global_mutex_);
      if (global_running_) return tell(false);  // another map's: none for this one now
    }
    log_info("map " + std::to_string(wait->map) + ": a session ended in it, " +
             std::to_string(since_global_[wait->map].keyframes) +
             " keyframes at its last global bundle adjustment: " + "one more");
    stop_global_adjustment();  // ended: joins its thread
    start_global_adjustment(wait->map, GlobalAdjustmentCause::kStreamEnd, wait);
  } catch (...) {
    tell(false);
    throw;
  }
}

void LoopCloser::forget_merged_maps() {
  std::erase_if(since_global_, [&](const auto& entry) { return !atlas_.map(entry.first); });
}

bool LoopCloser::refinement_due(MapId map_id, double growth, bool at_stream_end) {
  const auto map = atlas_.map(map_id);
  if (!map) return false;
  const auto it = since_global_.find(map_id);
  if (it == since_global_.end()) return false;
  const std::size_t keyframes = map->keyframe_count();
  // A single camera's initialised inertial map takes its scale from the IMU
  // alone: at a session's end it is adjusted once more with every inertial
  // term, however many sessions mapped it.
  const bool imu_scale =
      at_stream_end && options_.stream_end_imu_scale && options_.monocular && map->inertial_state().has_value();
  return (it->second.streams.size() >= 2 || imu_scale) && keyframes >= options_.shared_map_refinement_min_keyframes &&
         static_cast<double>(keyframes) >= (1.0 + growth) * static_cast<double>(it->second.keyframes);
}

void LoopCloser::wait_until_idle() {
  worker_.wait_until_idle();
  // A global adjustment is only started by the worker, which is idle now.
  std::unique_lock lock(global_mutex_);
  global_cv_.wait(lock, [&] { return !global_running_; });
}

void LoopCloser::finish() {
  std::exception_ptr fatal;
  try {
    worker_.finish();
  } catch (...) {
    fatal = std::current_exception();
  }
  if (global_thread_.joinable()) global_thread_.join();  // let it finish and merge
  if (fatal) std::rethrow_exception(fatal);
}

LoopClosingStats LoopCloser::stats() const {
  LoopClosingStats out;
  {
    std::lock_guard lock(stats_mutex_);
    out = stats_;
  }
  out.errors = worker_.errors();
  return out;
}

void LoopCloser::process(const Item& item) {
  if (item.stream_end) return handle_stream_end(item.stream_end);
  const std::shared_ptr<KeyFrame>& keyframe = item.keyframe;
  Recognizers& recognizers = this->recognizers(item.stream);
  const auto map = atlas_.map(keyframe->map_id());
  // A monocular map is of free scale until an IMU or a merge into a metric
  // map makes it metric.
  const bool free_scale = options_.monocular && map && !map->metric_scale();
  // A single camera fusing its IMU looks for merges once its map's IMU is
  // initialised: joined earlier, the session would go on in the other map
  // with no estimate of its own IMU's biases (measured: the left camera of
  // MH_02 merged 1 s in into a stereo-inertial map of MH_01 ended 0.15 m off,
  // against 0.013 m in a map of its own).
  const bool imu_pending = options_.monocular && options_.global.inertial && map && !map->inertial_state();
  if (recognizers.merges && !imu_pending) {
    // ORB-SLAM3 looks for a merge first: a keyframe that joins another map is
    // not also taken as a loop.
    const auto start = std::chrono::steady_clock::now();
    const bool similarity = map && merges_in_sim3(*map, options_.monocular, options_.settled_inertial_refinements);
    const PlaceRecognitionStep step = recognizers.merges->process(keyframe, similarity);
    {
      std::lock_guard lock(stats_mutex_);
      stats_.merge_search_ms.add(ms_since(start));
    }
    if (step.match && !step.match->same_map() && merge_live(*step.match)) return;
  }
  const auto start = std::chrono::steady_clock::now();
  const PlaceRecognitionStep step = recognizers.loops.process(keyframe, free_scale);
  {
    std::lock_guard lock(stats_mutex_);
    ++stats_.keyframes;
    stats_.place_recognition_ms.add(ms_since(start));
    if (step.hypothesis) ++stats_.hypotheses;
  }
  if (step.match && step.match->same_map()) {
    close_loop(*step.match);
    return;
  }
  if (adjust_inertial_map(item)) return;
  refine_shared_map(item);
}

bool LoopCloser::adjust_inertial_map(const Item& item) {
  const auto map = atlas_.map(item.keyframe->map_id());
  if (!map || !options_.global_bundle_adjustment || !map->take_inertial_adjustment_request()) return false;
  // A running adjustment was solved before the map's new inertial state (and
  // in its former frame, which apply_global_adjustment drops): this one
  // replaces it.
  stop_global_adjustment();
  start_global_adjustment(map->id(), GlobalAdjustmentCause::kInertial);
  return true;
}

void LoopCloser::refine_shared_map(const Item& item) {
  const auto map = atlas_.map(item.keyframe->map_id());
  if (!map) return;
  forget_merged_maps();
  since_global_[map->id()].streams.insert(item.stream);  // a stream's end asks too (handle_stream_end)
  if (!options_.global_bundle_adjustment || options_.shared_map_refinement_growth <= 0.0 ||
      !refinement_due(map->id(), options_.shared_map_refinement_growth, false))
    return;
  const SinceGlobalAdjustment& since = since_global_[map->id()];
  const std::size_t keyframes = map->keyframe_count();
  {
    std::lock_guard lock(global_mutex_);
    if (global_running_) return;  // that one goes on; a later keyframe asks again
  }
  log_info("map " + std::to_string(map->id()) + ": " + std::to_string(since.streams.size()) +
           " sessions mapped it since its last global bundle adjustment (" + std::to_string(since.keyframes) +
           " keyframes then, " + std::to_string(keyframes) + " now): one more");
  stop_global_adjustment();  // ended: joins its thread
  start_global_adjustment(map->id(), GlobalAdjustmentCause::kSharedMap);
}

void LoopCloser::close_loop(const PlaceMatch& loop) {
  stop_global_adjustment();
  const auto map = atlas_.map(loop.current->map_id());
  if (!map) return;
  LoopCorrectionStats correction;
  {
    std::lock_guard lock(correction_mutex_);
    MappingPause pause(mapping_, map->id());
    const auto whole = atlas_.lock_maps_exclusive();  // tracking sees the map before or after
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
    closed.T_cur_m = rigid_pose_c_w(loop.S_cur_m);
    closed.scale = loop.S_cur_m.s;
    closed.matches = loop.matches;
    closed.correction = correction;
    stats_.loops.push_back(closed);
  }
  if (options_.global_bundle_adjustment) start_global_adjustment(map->id(), GlobalAdjustmentCause::kLoop);
}

bool LoopCloser::merge_live(const PlaceMatch& match) {
  const MapId source = match.current->map_id();
  const MapId target = match.matched->map_id();
  const auto source_map = atlas_.map(source), target_map = atlas_.map(target);
  if (source == target || !source_map || !target_map) return false;
  if (!merge_keeps_scale(*source_map, *target_map)) {
    log_info("live merge: map " + std::to_string(source) + " is metric and map " + std::to_string(target) +
             " is not; not merged");
    return false;
  }
  if (wiring_.hold_map && !wiring_.hold_map(source, target)) {
    log_info("live merge: map " + std::to_string(target) + " was taken by another session meanwhile; not merged");
    return false;
  }
  stop_global_adjustment();  // it works on the source map, which is about to go
  MapMergeStats merged;
  {
    std::lock_guard lock(correction_mutex_);
    MappingPause pause(mapping_, source, target);
    merged = merge_maps(atlas_, match, cam_, options_.merge);  // holds the maps exclusive
    mapping_.merged(source, target);
  }
  log_info("live merge: map " + std::to_string(source) + " merged into map " + std::to_string(target) +
           " at keyframe " + std::to_string(match.current->id()) + " ~ " + std::to_string(match.matched->id()) + " (" +
           std::to_string(match.matches) + " matches, " + std::to_string(merged.keyframes_moved) +
           " keyframes moved, " + std::to_string(merged.points_fused) + " points fused, " + std::to_string(merged.ms) +
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
  if (wiring_.on_merged) wiring_.on_merged(record);
  if (options_.global_bundle_adjustment) start_global_adjustment(target, GlobalAdjustmentCause::kMerge);
  return true;
}

void LoopCloser::stop_global_adjustment() {
  if (!global_thread_.joinable()) return;
  stop_global_.store(true);
  global_thread_.join();
  stop_global_.store(false);
}

void LoopCloser::start_global_adjustment(MapId map_id, GlobalAdjustmentCause cause,
                                         std::shared_ptr<StreamEndWait> wait) {
  {
    std::lock_guard lock(global_mutex_);
    global_running_ = true;
    global_map_ = map_id;
    if (wait) global_waits_.push_back(std::move(wait));
  }
  if (const auto map = atlas_.map(map_id)) since_global_[map_id] = {map->keyframe_count(), {}};
  global_thread_ = std::thread([this, map_id, cause] {
    set_current_thread_nice(options_.worker_nice);
    set_current_thread_name("global BA");
    bool applied = false;
    try {
      const auto map = atlas_.map(map_id);
      if (map) {
        const auto start = std::chrono::steady_clock::now();
        const GlobalBundleAdjustmentResult result =
            global_bundle_adjustment(*map, *cam_.camera, cam_.bf,
                                     with_level_sigma2(options_.global, cam_.pyramid.level_sigma2()), &stop_global_);
        if (!result.stopped) {
          std::lock_guard lock(correction_mutex_);
          MappingPause pause(mapping_, map_id);
          const auto whole = atlas_.lock_maps_exclusive();  // tracking sees the map before or after
          apply_global_adjustment(*map, result, cam_.pyramid);
          applied = true;
        }
        GlobalAdjustmentRun run{
            cause, result.keyframes, result.points, result.inertial_edges, ms_since(start) * 1e-3, result.stopped};
        log_info(std::string("global bundle adjustment (") + to_string(cause) + "): " + std::to_string(run.keyframes) +
                 " keyframes, " + std::to_string(run.inertial_edges) + " inertial edges, " +
                 std::to_string(run.seconds) + " s" + (run.interrupted ? " (interrupted)" : ""));
        std::lock_guard lock(stats_mutex_);
        stats_.global_adjustments.push_back(run);
      }
    } catch (...) {
      worker_.record_failure("global bundle adjustment of map " + std::to_string(map_id));
    }
    std::lock_guard lock(global_mutex_);
    for (const auto& waiting : global_waits_) {
      waiting->done = true;
      waiting->applied = applied;
    }
    global_waits_.clear();
    global_running_ = false;
    global_map_ = kInvalidMapId;
    global_cv_.notify_all();
  });
}

}  // namespace orbatlas
