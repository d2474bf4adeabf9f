#include "core/server/map_merge_worker.h"

#include <chrono>

#include "core/common/log.h"
#include "core/common/stopwatch.h"
#include "core/optimization/apply_global_adjustment.h"

namespace orbatlas {

void MapMergeWorkerOptions::check() const {
  ORBATLAS_CHECK(queue_capacity > 0, "map merging: queue_capacity must be > 0, not " << queue_capacity);
  ORBATLAS_CHECK(worker_nice >= 0 && worker_nice <= 19,
                 "map merging: worker_nice must be in 0..19, not " << worker_nice);
  recognition.check();
  merge.check();
  global.check();
}

MapMergeWorker::MapMergeWorker(Atlas& atlas, MapLeases& leases, MayMerge may_merge, OnMerged on_merged,
                               MapMergeWorkerOptions options)
    : atlas_(atlas),
      leases_(leases),
      may_merge_(std::move(may_merge)),
      on_merged_(std::move(on_merged)),
      options_((options.check(), std::move(options))),
      worker_(
          QueueWorkerOptions::own_thread("map merging", options_.queue_capacity, QueueWorkerOptions::kNeverFatal,
                                         options_.worker_nice),
          [this](MergeRequest& request) { run_one(request); },
          [](const MergeRequest& request) { return "the merge request for map " + std::to_string(request.map); }) {}

MapMergeWorker::~MapMergeWorker() { stop(); }

bool MapMergeWorker::submit(MergeRequest request) {
  {
    std::lock_guard lock(mutex_);
    ++stats_.requests;
  }
  if (!stopping_.load() && worker_.try_push(std::move(request))) return true;
  std::lock_guard lock(mutex_);
  ++stats_.skipped;
  log_warn("map merging: a request was dropped (queue full or stopping)");
  return false;
}

void MapMergeWorker::wait_until_idle() { worker_.wait_until_idle(); }

void MapMergeWorker::stop() {
  stopping_.store(true);
  worker_.stop();
}

MapMergeWorkerStats MapMergeWorker::stats() const {
  MapMergeWorkerStats out;
  {
    std::lock_guard lock(mutex_);
    out = stats_;
  }
  out.pending = worker_.in_flight();
  out.skipped += worker_.discarded();
  const WorkerErrorCounts errors = worker_.errors();
  out.errors = errors.errors;
  out.last_error = errors.last;
  return out;
}

void MapMergeWorker::run_one(const MergeRequest& request) {
  // The leases the request took go back whether it merged, found nothing or
  // failed half-way (its maps stay as the last complete edit left them).
  struct ReleaseLeases {
    MapLeases& leases;
    ~ReleaseLeases() { leases.release_all(kMergeWorkerLease); }
  } release{leases_};
  if (stopping_.load()) return;
  const std::optional<MapId> put_off_for = process(request);
  if (stopping_.load()) return;
  if (put_off_for)
    on_put_off_(request.map, *put_off_for);
  else if (on_done_)
    on_done_(request.map);
}

std::optional<MapId> MapMergeWorker::process(const MergeRequest& request) {
  const auto source = atlas_.map(request.map);
  if (!source || !request.cam || !request.cam->camera) return std::nullopt;            // merged away meanwhile
  if (!leases_.claim_exclusive(kMergeWorkerLease, source->id())) return std::nullopt;  // a session works in it again
  const auto search_start = std::chrono::steady_clock::now();

  PlaceRecognitionOptions recognition = options_.recognition;
  recognition.scope = PlaceScope::kOtherMaps;
  const MapId source_id = source->id();
  recognition.may_use_map = [this, source_id](MapId target) {
    const auto holders = leases_.holders(target);
    return (holders.empty() || holders == std::vector<SessionId>{kMergeWorkerLease}) &&
           (!may_merge_ || may_merge_(source_id, target));
  };
  PlaceRecognizer recognizer(atlas_.keyframe_index(), *request.cam, recognition);

  // A single camera's map of free scale is matched as a similarity.
  const bool similarity = merges_in_sim3(*source, request.single_camera, options_.settled_inertial_refinements);
  std::optional<PlaceMatch> match;
  std::size_t searched = 0;
  for (const auto& kf : source->keyframes()) {
    if (stopping_.load()) return std::nullopt;
    if (kf->id() < request.first_keyframe) continue;
    ++searched;
    PlaceRecognitionStep step = recognizer.process(kf, similarity);
    if (step.match) {
      match = std::move(step.match);
      break;
    }
  }
  {
    std::lock_guard lock(mutex_);
    ++stats_.maps_searched;
    stats_.keyframes_searched += searched;
  }
  if (!match) {
    log_info("map merging: map " + std::to_string(source_id) + " (" + std::to_string(searched) +
             " keyframes searched) shares no verified place with another map");
    if (options_.global_bundle_adjustment && options_.refine_unmerged && searched > 0 && !stopping_.load()) {
      MapRefinement refinement{source_id};
      const GlobalBundleAdjustmentResult result = refine(*source, request, &refinement.seconds);
      refinement.keyframes = result.keyframes;
      refinement.inertial_edges = result.inertial_edges;
      refinement.interrupted = result.stopped;
      std::lock_guard lock(mutex_);
      push_recent(stats_.refinements, refinement);
      ++stats_.refinements_total;
    }
    return std::nullopt;
  }
  const MapId target_id = match->matched->map_id();
  const bool put_off = static_cast<bool>(on_put_off_);
  if (put_off && target_writable_ && !target_writable_(target_id)) {
    log_info("map merging: map " + std::to_string(source_id) + " found its place in map " + std::to_string(target_id) +
             ", which another replica writes; the merge waits for that map");
    return target_id;
  }
  if (!leases_.claim_exclusive(kMergeWorkerLease, target_id))  // a session entered it just now
    return put_off ? std::optional<MapId>(target_id) : std::nullopt;
  if (const auto target = atlas_.map(target_id); !target || !merge_keeps_scale(*source, *target)) {
    log_info("map merging: map " + std::to_string(source_id) + " is metric and map " + std::to_string(target_id) +
             " is not (or is gone); not merged");
    return std::nullopt;
  }

  MergeRecord record;
  record.current = match->current->id();
  record.matched = match->matched->id();
  record.matches = match->matches;
  record.verified_keyframes = match->verified_keyframes;
  record.search_ms = ms_since(search_start);
  record.keyframes_searched = searched;
  record.merge = merge_maps(atlas_, *match, *request.cam, options_.merge);
  leases_.forget(source_id);
  log_info("map merging: map " + std::to_string(source_id) + " merged into map " + std::to_string(target_id) +
           " (keyframe " + std::to_string(record.current) + " ~ " + std::to_string(record.matched) + ", " +
           std::to_string(record.matches) + " matches, " + std::to_string(record.merge.keyframes_moved) +
           " keyframes moved, " + std::to_string(record.merge.points_fused) + " points fused)");

  if (options_.global_bundle_adjustment) {
    if (const auto map = atlas_.map(target_id)) {
      const GlobalBundleAdjustmentResult result = refine(*map, request, &record.ba_seconds);
      record.ba_keyframes = result.keyframes;
      record.ba_inertial_edges = result.inertial_edges;
      record.ba_interrupted = result.stopped;
    }
  }
  {
    std::lock_guard lock(mutex_);
    push_recent(stats_.merges, record);
    ++stats_.merges_total;
  }
  if (on_merged_) on_merged_(record);
  return std::nullopt;
}

GlobalBundleAdjustmentResult MapMergeWorker::refine(Map& map, const MergeRequest& request, double* seconds) {
  const auto start = std::chrono::steady_clock::now();
  const FrameCamera& cam = *request.cam;
  GlobalBundleAdjustmentOptions global = with_level_sigma2(options_.global, cam.pyramid.level_sigma2());
  if (request.inertial) global.inertial = request.inertial;
  const GlobalBundleAdjustmentResult result = global_bundle_adjustment(map, *cam.camera, cam.bf, global, &stopping_);
  if (!result.stopped) {
    const auto whole = atlas_.lock_maps_exclusive();  // localisations see the map before or after
    apply_global_adjustment(map, result, cam.pyramid);
  }
  *seconds = ms_since(start) * 1e-3;
  return result;
}

}  // namespace orbatlas
