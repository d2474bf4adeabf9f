#include "core/server/atlas_service.h"

#include "core/server/shared_merges.h"

#include <chrono>
#include <cmath>
#include <fstream>
#include <sstream>

#include "core/common/data_paths.h"
#include "core/common/log.h"
#include "core/common/process_memory.h"
#include "core/io/tum_trajectory.h"
#include "core/persistence/atlas_store.h"
#include "core/persistence/map_rigs.h"
#include "core/slam/mono_localizer.h"
#include "core/slam/slam_stats.h"
#include "core/slam/slam_system.h"
#include "core/server/service_error.h"
#include "core/server/session_rules.h"
#include "core/vocabulary/default_vocabulary.h"

namespace orbatlas {
namespace {

TimestampNs unix_now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace

void AtlasServiceOptions::check() const {
  ORBATLAS_CHECK(!db.empty(), "the server needs a database path (--db)");
  ORBATLAS_CHECK(max_live_sessions > 0, "server: max_live_sessions must be > 0, not " << max_live_sessions);
  ORBATLAS_CHECK(!std::isnan(idle_timeout_s), "server: idle_timeout_s is not a number");
  ORBATLAS_CHECK(
      std::isfinite(finish_refinement_wait_s) && finish_refinement_wait_s >= 0.0 && finish_refinement_wait_s <= 3600.0,
      "server: finish_refinement_wait_s must be in 0..3600, not " << finish_refinement_wait_s);
  ORBATLAS_CHECK(loop_queue > 0, "server: loop_queue must be > 0, not " << loop_queue);
  ORBATLAS_CHECK(background_nice >= 0 && background_nice <= 19,
                 "server: background_nice must be in 0..19, not " << background_nice);
  slam.check();
  merging.check();
  checkpoints.check();
  replica.check();
}

namespace {

// Every background worker of the sessions (their options are copied from
// these) at the server's background nice value.
AtlasServiceOptions with_background_nice(AtlasServiceOptions options) {
  options.slam.mapper.worker_nice = options.background_nice;
  options.slam.loop.worker_nice = options.background_nice;
  options.merging.worker_nice = options.background_nice;
  options.checkpoints.worker_nice = options.background_nice;
  return options;
}

}  // namespace

AtlasService::AtlasService(AtlasServiceOptions options)
    : options_((options.check(), with_background_nice(std::move(options)))),
      db_lock_(options_.db.empty() ? nullptr : std::make_unique<DatabaseLock>(options_.db, DatabaseLockMode::kShared)),
      replica_(std::make_unique<ReplicaRegistry>(options_.db, options_.replica)),
      ownership_(replica_->shared() ? std::make_unique<MapOwnership>(*replica_, options_.db.string()) : nullptr),
      shared_merges_(replica_->shared() ? std::make_unique<SharedMerges>(options_.db.string()) : nullptr),
      vocabulary_(Vocabulary::load(options_.vocabulary.empty() ? default_vocabulary_path() : options_.vocabulary)),
      loop_worker_(std::make_shared<SerialWorker>(options_.loop_queue, options_.background_nice, "loop closing")) {
  const auto start = std::chrono::steady_clock::now();
  {
    // A shared atlas: the maps nobody owns and those of dead replicas are
    // claimed before they are read, so what is read is what they last committed.
    const std::vector<MapId> claimed = ownership_ ? ownership_->claim_free_and_dead() : std::vector<MapId>{};
    // The versions before the maps are read: a map changed meanwhile is read again later.
    if (ownership_)
      for (const MapOwnership::Owned& o : ownership_->owners()) seen_versions_[o.map] = o.version;
    AtlasStore store = AtlasStore::open(options_.db, vocabulary_.hash());
    const AtlasLoadReport loaded = store.load_atlas(atlas_, &vocabulary_);
    if (ownership_) start_as_replica(claimed);
    atlas_.index_all_keyframes();
    if (db_lock_->previous_holder_crashed()) {
      skip_ids_after_crash(atlas_);
      log_warn("atlas " + store.location() +
               ": the previous server stopped without its final checkpoint (killed?); what it did after its last "
               "checkpoint is lost, and new ids continue past any it may have handed out");
    }
    // Mapping, merging and entering (leases): only the maps this replica writes.
    for (const auto& map : atlas_.maps())
      if (!ownership_ || ownership_->owns(map->id())) leases_.add_free(map->id());
    const std::map<SessionId, SessionRecord> records = store.load_session_records();
    for (const SessionInfo& info : store.load_sessions()) {
      const auto anchors = store.load_trajectory(info.id);
      // The rig each stored map was made with (for merging, and for entering
      // it): its stereo sessions' cameras (a single camera only localised there).
      record_map_rigs(atlas_, info, anchors, map_rigs_);
      // The trajectory itself stays in the database (read when asked for).
      const auto record = records.find(info.id);
      sessions_[info.id] = std::make_shared<LiveSession>(
          info, record == records.end() ? std::nullopt : std::optional<SessionRecord>(record->second), anchors);
      if (!ownership_ || replica_id_range(replica_->id(), kReplicaMapIdShift).contains(info.id))
        next_session_ = std::max(next_session_, info.id + 1);
    }
    log_info("atlas " + store.location() + ": " + std::to_string(loaded.maps) + " maps, " +
             std::to_string(loaded.keyframes) + " keyframes, " + std::to_string(loaded.map_points) + " map points, " +
             std::to_string(sessions_.size()) + " sessions loaded in " +
             std::to_string(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()) + " s");
  }
  CheckpointOptions checkpoints = options_.checkpoints;
  if (ownership_) {
    checkpoints.writable_maps = [this](SqlConnection& db, const std::vector<MapId>& candidates,
                                       const std::unordered_set<MapId>& gone) {
      return ownership_->writable(db, candidates, gone);
    };
    checkpoints.maps_changed = [this](SqlConnection& db, const std::vector<MapId>& maps) {
      ownership_->changed(db, maps);
    };
  }
  checkpointer_ = std::make_unique<AtlasCheckpointer>(atlas_, options_.db, vocabulary_.hash(), checkpoints);
  store_.emplace(AtlasStore::open(options_.db, vocabulary_.hash()));
  if (options_.merge_maps)
    merger_ = std::make_unique<MapMergeWorker>(
        atlas_, leases_, [this](MapId a, MapId b) { return rigs_match(a, b); },
        [this](const MergeRecord& r) { merged(r); }, options_.merging);
  if (merger_ && shared_merges_) {
    merger_->set_on_done([this](MapId map) {
      try {
        shared_merges_->remove(map);
      } catch (const std::exception& e) {
        log_warn("map merging: the stored merge work of map " + std::to_string(map) + " stays: " + e.what());
      }
      {
        std::lock_guard lock(merge_work_mutex_);
        claimed_merges_.erase(map);
      }
      wake_merge_work();  // the next row
    });
    merger_->set_put_off([this](MapId target) { return ownership_->owns(target); },
                         [this](MapId source, MapId target) { merge_put_off(source, target); });
  }
  if (options_.idle_timeout_s > 0) idle_thread_ = std::thread([this] { finish_idle_sessions(); });
  if (ownership_) {
    takeover_thread_ = std::thread([this] { take_over_until_stopped(); });
    // The merge work left with the maps this replica writes now is claimed there too.
    merge_work_thread_ = std::thread([this] { share_merge_work_until_stopped(); });
  }
}

void AtlasService::finish_idle_sessions() {
  const auto timeout = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double>(std::min(options_.idle_timeout_s, 3.15e7)));
  std::unique_lock lock(mutex_);
  while (!shut_down_) {
    const auto now = std::chrono::steady_clock::now();
    std::vector<SessionId> idle;
    auto next = std::chrono::steady_clock::time_point::max();
    for (const auto& [id, s] : sessions_) {
      if (s->state() != SessionState::kActive) continue;
      const auto deadline = s->last_activity() + timeout;
      if (deadline <= now) {
        idle.push_back(id);
      } else {
        next = std::min(next, deadline);
      }
    }
    if (idle.empty()) {
      // Until the earliest deadline (a new session's is later than all of them).
      if (next == std::chrono::steady_clock::time_point::max()) {
        idle_wake_.wait(lock);
      } else {
        idle_wake_.wait_until(lock, next);
      }
      continue;
    }
    lock.unlock();
    for (const SessionId id : idle) {
      try {
        // Activity may have come meanwhile: only a session still idle is ended.
        const auto live = session(id);
        if (std::chrono::steady_clock::now() - live->last_activity() < timeout) continue;
        log_info("session " + std::to_string(id) + ": no frame for " + std::to_string(options_.idle_timeout_s) +
                 " s; finishing it (its data is stored)");
        sessions_timed_out_.Increment();  // counted as it ends (the status says finished right after)
        finish_session(id, "idle_timeout");
      } catch (const std::exception& e) {
        log_warn("session " + std::to_string(id) + ": finishing it after its idle timeout failed: " + e.what());
      }
    }
    lock.lock();
  }
}

AtlasService::~AtlasService() {
  try {
    shutdown();
  } catch (const std::exception& e) {
    log_warn(std::string("server shutdown: ") + e.what());
  }
}

std::unique_ptr<SessionSlam> AtlasService::make_slam_system(SessionId id, const MapRig& rig,
                                                            const SlamSettings& settings, SessionMode mode) {
  SlamSystemOptions slam_options = options_.slam;
  SessionWiring wiring;
  if (mode == SessionMode::kLocalize) {
    // Tracks in the stored maps of its own rig and changes nothing: no lease,
    // no keyframes, no loop closing or merging.
    slam_options.tracker.localization_only = true;
    slam_options.relocalization = true;
    slam_options.loop_closing = false;
    slam_options.live_merging = false;
    wiring.may_enter_map = [this, cameras = rig.cameras](MapId map) { return cameras_match(cameras, map); };
    try {
      return std::make_unique<SlamSystem>(atlas_, settings, vocabulary_, slam_options, std::move(wiring));
    } catch (const std::exception& e) {
      throw ServiceError(ServiceErrorKind::kBadRequest, "bad_config",
                         std::string("cannot start a session with these settings: ") + e.what());
    }
  }
  // Stored maps of its own rig only (local mapping would adjust another rig's
  // keyframes with this session's camera), also maps other sessions are
  // mapping right now: it then maps with them (one mapper per map). A session
  // that fuses its IMU maps only where sessions that fuse theirs mapped, and
  // one that does not only where theirs did not (one mapping, one set of options).
  wiring.may_enter_map = [this, id, rig](MapId map) { return mapping_rig_matches(rig, map) && leases_.claim(id, map); };
  slam_options.tracker.start_in_stored_map = options_.start_in_stored_maps;
  slam_options.live_merging = options_.merge_maps && options_.live_merging;
  slam_options.shared_map_finish_wait_s = options_.finish_refinement_wait_s;
  wiring.mapping = [this, rig](const FrameCamera& cam, const MappingWorkersOptions& mapping) {
    return mapping_for(rig, cam, mapping);
  };
  try {
    return std::make_unique<SlamSystem>(atlas_, settings, vocabulary_, slam_options, std::move(wiring));
  } catch (const std::exception& e) {
    throw ServiceError(ServiceErrorKind::kBadRequest, "bad_config",
                       std::string("cannot start a session with these settings: ") + e.what());
  }
}

SessionId AtlasService::create_session(const SessionRequest& request) {
  check_session_name(request.name);
  check_max_lag(request.max_lag_s);
  const LoadedSettings loaded = load_settings(request.settings);
  const SensorType sensor = session_sensor(request.sensor, loaded.settings);
  // A single camera maps (monocular SLAM, its own maps at their own scale;
  // metric with its IMU, mono_inertial) or localises in the stored maps,
  // tracked visually, its IMU checked and counted. A single camera may also
  // be the first camera of a stereo config.
  const bool single_camera = is_single_camera(sensor);
  const SessionMode mode = session_mode(request.mode, sensor, loaded.settings);
  const bool monocular_mapping = single_camera && mode == SessionMode::kMap;
  if (!single_camera && !loaded.settings.is_stereo() && !loaded.settings.is_rgbd())
    throw ServiceError(ServiceErrorKind::kBadRequest, "bad_config",
                       "config '" + loaded.label + "' is not a stereo rig (Camera2.* missing) nor an RGB-D camera");
  if (!single_camera && (sensor == SensorType::kRgbd) != loaded.settings.is_rgbd())
    throw ServiceError(ServiceErrorKind::kBadRequest, "bad_config",
                       "sensor '" + std::string(sensor_type_name(sensor)) + "' with config '" + loaded.label + "' (a " +
                           sensor_type_name(loaded.settings.sensor) +
                           " config): an RGB-D session needs an rgbd config and the reverse");

  SessionId id = 0;
  {
    std::lock_guard lock(mutex_);
    if (shut_down_) throw ServiceError(ServiceErrorKind::kUnavailable, "shutting_down", "the server is shutting down");
    std::size_t live = 0;
    for (const auto& [_, s] : sessions_) live += s->state() == SessionState::kActive ? 1 : 0;
    if (live >= options_.max_live_sessions)
      throw ServiceError(ServiceErrorKind::kUnavailable, "too_many_sessions",
                         std::to_string(live) + " sessions are live; the limit is " +
                             std::to_string(options_.max_live_sessions) + " (finish one first)");
    id = next_session_++;
  }
  SessionInfo info;
  info.id = id;
  info.name = request.name.empty() ? "session " + std::to_string(id) : request.name;
  info.sensor = sensor;
  info.created_ns = unix_now_ns();
  info.cameras.push_back(loaded.settings.camera0);
  if (loaded.settings.camera1) info.cameras.push_back(*loaded.settings.camera1);

  // As SlamSystem decides whether it fuses the IMU.
  std::optional<GlobalBundleAdjustmentOptions::Inertial> inertial;
  const bool fuses_imu = mode == SessionMode::kMap && options_.slam.inertial && loaded.settings.imu &&
                         (!single_camera || sensor == SensorType::kMonocularInertial);
  if (fuses_imu)
    inertial = GlobalBundleAdjustmentOptions::Inertial{
        // A single camera's body is its camera (docs/monocular.md).
        .T_b_i = single_camera ? single_camera_T_b_c(loaded.settings).inverse() * loaded.settings.imu->T_b_i
                               : loaded.settings.imu->T_b_i,
        .max_chain_keyframes = options_.slam.mapper.inertial.refinement_max_keyframes};
  const MapRig rig{info.cameras, inertial.has_value(), monocular_mapping};

  std::unique_ptr<SessionSlam> slam;
  if (monocular_mapping) {
    slam = make_slam_system(id, rig, monocular_settings(loaded.settings, sensor), mode);
  } else if (single_camera) {
    MonoLocalizerOptions mono;
    mono.tracker = options_.slam.tracker;
    SessionWiring wiring;  // it reads any stored map, holding no lease (it changes nothing)
    try {
      slam = std::make_unique<MonoLocalizer>(atlas_, loaded.settings, vocabulary_, mono, std::move(wiring));
    } catch (const std::exception& e) {
      throw ServiceError(ServiceErrorKind::kBadRequest, "bad_config",
                         std::string("cannot start a single-camera session with these settings: ") + e.what());
    }
  } else {
    slam = make_slam_system(id, rig, loaded.settings, mode);
  }
  // Stored before its id is handed out: an id is never given twice, even when
  // the server dies before the session's first checkpoint.
  try {
    SessionRecord record;  // what it is before its first frame (an interrupted start shows it)
    record.mode = session_mode_name(mode);
    record.config = loaded.label;
    std::lock_guard lock(store_mutex_);
    store_->save_session(info);
    store_->save_session_record(id, record);
  } catch (const std::exception& e) {
    throw ServiceError(ServiceErrorKind::kUnavailable, "storage_failed",
                       std::string("cannot store the new session: ") + e.what());
  }
  auto live = std::make_shared<LiveSession>(info, loaded.label, std::move(slam), mode, request.max_lag_s);
  const SessionStart start{request.settings, atlas_.ids().peek(IdKind::keyframe), inertial, rig};
  {
    std::lock_guard lock(mutex_);
    sessions_[id] = live;
    session_starts_[id] = start;
  }
  if (mode == SessionMode::kMap)
    begin_session_work(id, StoredMerge{0, start.settings, start.first_keyframe, start.inertial, rig.monocular});
  idle_wake_.notify_all();
  // The checkpoint thread reads the frames through its own reference.
  checkpointer_->add_session(CheckpointSession{info, [live](std::size_t first) { return live->anchors_from(first); },
                                               [live] { return live->record(); }});
  sessions_created_.Increment();
  log_info("session " + std::to_string(id) + " started (" + info.name + ", config " + loaded.label + ")");
  return id;
}

std::shared_ptr<LiveSession> AtlasService::session(SessionId id) const {
  std::lock_guard lock(mutex_);
  const auto it = sessions_.find(id);
  if (it == sessions_.end()) throw_not_found("no session " + std::to_string(id));
  return it->second;
}

std::vector<std::shared_ptr<LiveSession>> AtlasService::sessions() const {
  std::lock_guard lock(mutex_);
  std::vector<std::shared_ptr<LiveSession>> out;
  for (const auto& [_, s] : sessions_) out.push_back(s);
  return out;
}

SessionStatus AtlasService::session_status(SessionId id) const {
  const auto live = session(id);
  SessionStatus status = live->status();
  if (status.map && !atlas_.map(*status.map)) {
    if (const auto last = live->last_anchor())
      if (const auto located = atlas_.locate_frame(*last)) status.map = located->first;
  }
  return status;
}

std::shared_ptr<MappingWorkers> AtlasService::mapping_for(const MapRig& rig, const FrameCamera& cam,
                                                          const MappingWorkersOptions& options) {
  std::lock_guard lock(mappings_mutex_);
  for (const RigMapping& m : mappings_)
    if (same_mapping_rig(m.rig, rig)) return m.workers;
  LoopCloserWiring wiring;
  wiring.shared_worker = loop_worker_;
  // Live merging into maps of the same rig, also those other sessions are
  // mapping now (their sessions and the merged map's then share the joined
  // map), never one the merging worker holds.
  // A metric rig (stereo, RGB-D) merges only into maps of metric scale.
  wiring.may_merge_into = [this, rig, metric = cam.bf > 0.0](MapId map) {
    const auto holders = leases_.holders(map);
    if (holders == std::vector<SessionId>{kMergeWorkerLease} || !mapping_rig_matches(rig, map)) return false;
    const auto target = metric ? atlas_.map(map) : nullptr;
    return !metric || (target && target->metric_scale());
  };
  wiring.hold_map = [this](MapId source, MapId target) { return leases_.share(source, target); };
  wiring.on_merged = [this](const LiveMerge& merge) { merged_live(merge); };
  auto workers = std::make_shared<MappingWorkers>(atlas_, cam, options, std::move(wiring));
  mappings_.push_back({rig, workers});
  return workers;
}

std::vector<MapId> AtlasService::end_session_storage(SessionId id) {
  const std::vector<MapId> held = leases_.held_by(id);
  const auto live = session(id);
  const MapRig rig = mapping_rig(id);
  if (live->mode() == SessionMode::kMap) {
    std::lock_guard lock(rigs_mutex_);
    for (const MapId map : held) map_rigs_.try_emplace(map, rig);
  }
  leases_.release_all(id);
  // The local mapping of maps nobody maps now ends (its thread goes); the
  // merging worker may take those maps from here on.
  std::shared_ptr<MappingWorkers> mapping;
  {
    std::lock_guard lock(mappings_mutex_);
    for (const RigMapping& m : mappings_)
      if (same_mapping_rig(m.rig, rig)) mapping = m.workers;
  }
  if (mapping)
    for (const MapId map : held)
      if (leases_.is_free(map)) mapping->retire(map);
  checkpointer_->end_session(id);
  return held;
}

FrameReply AtlasService::process_frame(SessionId id, TimestampNs t_ns, const cv::Mat& left, const cv::Mat& right,
                                       const FrameRequestTiming& timing) {
  const auto started = timing.started.value_or(std::chrono::steady_clock::now());
  const auto live = session(id);
  FrameReply reply;
  reply.session = id;
  try {
    const FrameOutcome out = live->process(t_ns, left, right);
    reply.result = out.result;
    reply.tracking_ms = out.tracking_ms;
    reply.skipped = out.skipped;
    reply.jump_m = out.jump_m;
    if (out.jump_m) live_pose_jumps_.Observe(*out.jump_m);
  } catch (const ServiceError& e) {
    if (e.code() == "session_failed") {
      end_session_storage(id);
      end_session_work(id);
    }
    throw;
  } catch (const DataError&) {
    frames_rejected_.Increment();
    throw;
  }
  if (reply.skipped) {
    frames_skipped_.Increment();
    return reply;  // nothing tracked: the leases and the checkpoints stay as they are
  }
  // A localisation holds no lease: it changes nothing, any number share a map.
  if (live->mode() != SessionMode::kLocalize) {
    leases_.settle(id, reply.result.tracked ? std::optional<MapId>(reply.result.map) : std::nullopt);
    if (reply.result.tracked) {
      // Known to be of this rig from its first frame: other sessions may enter it.
      // (Its rig is looked up only for a map not recorded yet: not on every frame.)
      bool known = false;
      {
        std::lock_guard lock(rigs_mutex_);
        known = map_rigs_.count(reply.result.map) > 0;
      }
      if (!known) {
        const MapRig rig = mapping_rig(id);
        std::lock_guard lock(rigs_mutex_);
        map_rigs_.try_emplace(reply.result.map, rig);
      }
    }
  }
  if (reply.result.keyframe) checkpointer_->notify_keyframe(id, reply.result.keyframe_id);
  frames_.Increment();
  tracking_latency_.Observe(reply.tracking_ms / 1000.0);
  const double request_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - started).count();
  live->note_request(timing.decode_ms, request_ms);
  frame_request_latency_.Observe(request_ms / 1000.0);
  return reply;
}

std::size_t AtlasService::add_imu(SessionId id, const std::vector<ImuSample>& samples) {
  return session(id)->add_imu(samples);
}

SessionStatus AtlasService::finish_session(SessionId id) { return finish_session(id, std::string()); }

SessionStatus AtlasService::finish_session(SessionId id, const std::string& ended_by) {
  const auto live = session(id);
  if (live->state() == SessionState::kStored)
    throw_conflict("session " + std::to_string(id) + " was stored by an earlier run; there is nothing to finish");
  const bool ended = live->finish(ended_by);
  if (ended) {
    const std::vector<MapId> held = end_session_storage(id);
    // The session's last frames and keyframes are on disk before the reply.
    if (!checkpointer_->checkpoint_now())
      throw ServiceError(ServiceErrorKind::kFailed, "storage_failed",
                         "session " + std::to_string(id) + " ended but could not be stored yet: " +
                             checkpointer_->stats().last_error + " (the server keeps retrying)");
    live->release_anchors();  // stored: the database answers for its trajectory from now on
    // A localising single camera only read the maps it held; a mapping one's
    // maps (of free scale, or with its IMU of a scale that may not have
    // settled) are merged as similarities (MergeRequest::single_camera).
    if (!is_single_camera(live->info().sensor) || live->mode() == SessionMode::kMap) submit_merges(id, held);
    end_session_work(id);  // after its maps' rows: a death in between leaves both, adopted as one
    // The session's SLAM objects (images, pyramids, rectification maps) are
    // gone: give the allocator's idle pages back, so a server that runs
    // session after session keeps a flat resident size.
    release_free_heap();
  }
  return live->status();
}

void AtlasService::shutdown() {
  std::vector<std::shared_ptr<LiveSession>> live;
  {
    std::lock_guard lock(mutex_);
    if (shut_down_) return;
    shut_down_ = true;
  }
  idle_wake_.notify_all();
  if (idle_thread_.joinable()) idle_thread_.join();  // it may be finishing a session: let it end
  takeover_wake_.notify_all();
  if (takeover_thread_.joinable()) takeover_thread_.join();
  merge_work_wake_.notify_all();
  if (merge_work_thread_.joinable()) merge_work_thread_.join();
  {
    std::lock_guard lock(mutex_);
    for (const auto& [_, s] : sessions_)
      if (s->state() == SessionState::kActive) live.push_back(s);
  }
  // Merging stops first (a running global adjustment is interrupted; a merge
  // already made is in the final checkpoint); the sessions below submit none
  // (on a shared atlas their stored work stays, for another replica to adopt).
  if (merger_) merger_->stop();
  for (const auto& s : live) {
    try {
      if (s->finish("shutdown")) log_info("session " + std::to_string(s->id()) + " finished by the shutdown");
    } catch (const std::exception& e) {
      log_warn(e.what());
    }
    end_session_storage(s->id());
  }
  {
    // Every session has finished above: the mappings finish (a running global
    // adjustment is waited for), then the loop-closing thread stops.
    std::vector<RigMapping> mappings;
    {
      std::lock_guard lock(mappings_mutex_);
      mappings.swap(mappings_);
    }
    for (const RigMapping& m : mappings) {
      try {
        m.workers->finish();
      } catch (const std::exception& e) {
        log_warn(std::string("mapping stopped with an error: ") + e.what());
      }
    }
  }
  loop_worker_->stop();
  checkpointer_->stop();  // the final, durable checkpoint
  const CheckpointStats stats = checkpointer_->stats();
  if (stats.failures > 0)
    log_warn("atlas checkpoints failed " + std::to_string(stats.failures) + " times; last: " + stats.last_error);
  {
    std::lock_guard lock(store_mutex_);
    store_.reset();
  }
  // Only a final checkpoint that stored everything counts as a clean stop.
  if (!stats.last_failed) {
    try {
      db_lock_->mark_stopped();
    } catch (const std::exception& e) {
      log_warn(e.what());
    }
  }
  replica_->stop();
}

}  // namespace orbatlas
