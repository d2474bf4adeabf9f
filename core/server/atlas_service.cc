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
      mappings_(options_.loop_queue, options_.background_nice),
      sessions_(options_.max_live_sessions),
      localizers_(atlas_, vocabulary_,
                  [dir = config_dir()](const SettingsSource& source) { return load_request_settings(source, dir); }) {
  // A shared atlas: the maps nobody owns and those of dead replicas are
  // claimed before they are read, so what is read is what they last committed;
  // the versions before the maps are read (a map changed meanwhile is read again later).
  const std::vector<MapId> claimed = ownership_ ? ownership_->claim_free_and_dead() : std::vector<MapId>{};
  std::map<MapId, std::int64_t> seen_versions;
  if (ownership_)
    for (const MapOwnership::Owned& o : ownership_->owners()) seen_versions[o.map] = o.version;
  load_atlas(claimed);
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
  if (ownership_) {
    replicas_ = std::make_unique<ReplicaCoordinator>(
        ReplicaParts{.db = options_.db,
                     .lease_s = options_.replica.lease_s,
                     .vocabulary = &vocabulary_,
                     .atlas = &atlas_,
                     .leases = &leases_,
                     .checkpointer = checkpointer_.get(),
                     .replica = replica_.get(),
                     .ownership = ownership_.get(),
                     .shared_merges = shared_merges_.get(),
                     .merger = merger_.get(),
                     .sessions = &sessions_,
                     .rigs = &rigs_,
                     .merge_camera = [this](const SettingsSource& s) { return localizers_.map_camera(s); }},
        std::move(seen_versions));
    if (merger_) {
      merger_->set_on_done([this](MapId map) { replicas_->merge_done(map); });
      merger_->set_put_off([this](MapId target) { return ownership_->owns(target); },
                           [this](MapId source, MapId target) { replicas_->merge_put_off(source, target); });
    }
  }
  if (options_.idle_timeout_s > 0)
    sessions_.expire_idle_sessions(options_.idle_timeout_s, [this](SessionId id) {
      log_info("session " + std::to_string(id) + ": no frame for " + std::to_string(options_.idle_timeout_s) +
               " s; finishing it (its data is stored)");
      metrics_.session_timed_out();  // counted as it ends (the status says finished right after)
      finish_session(id, "idle_timeout");
    });
  if (replicas_) replicas_->start();
}

void AtlasService::load_atlas(const std::vector<MapId>& claimed) {
  const auto start = std::chrono::steady_clock::now();
  AtlasStore store = AtlasStore::open(options_.db, vocabulary_.hash());
  const AtlasLoadReport loaded = store.load_atlas(atlas_, &vocabulary_);
  if (ownership_) {
    // Ids of this replica's own ranges from here on; the maps claimed before the load may be written.
    confine_ids_to_replica(atlas_, sessions_, replica_->id());
    ownership_->ready(claimed);
    if (!claimed.empty())
      log_info("replica " + std::to_string(replica_->id()) + " writes " + std::to_string(claimed.size()) +
               " stored map(s) that no live replica writes (their replica stopped or died, or none ever did)");
  }
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
    rigs_.record_session(atlas_, info, anchors);
    // The trajectory itself stays in the database (read when asked for).
    const auto record = records.find(info.id);
    const bool own_id = !ownership_ || replica_id_range(replica_->id(), kReplicaMapIdShift).contains(info.id);
    sessions_.add_stored(
        std::make_shared<LiveSession>(
            info, record == records.end() ? std::nullopt : std::optional<SessionRecord>(record->second), anchors),
        own_id);
  }
  log_info("atlas " + store.location() + ": " + std::to_string(loaded.maps) + " maps, " +
           std::to_string(loaded.keyframes) + " keyframes, " + std::to_string(loaded.map_points) + " map points, " +
           std::to_string(sessions_.size()) + " sessions loaded in " +
           std::to_string(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()) + " s");
}

AtlasService::~AtlasService() {
  try {
    shutdown();
  } catch (const std::exception& e) {
    log_warn(std::string("server shutdown: ") + e.what());
  }
}

std::unique_ptr<SessionSlam> AtlasService::make_slam_system(SessionId id, const MapRig& rig,
                                                            const SlamSettings& settings, SessionMode mode,
                                                            bool real_time) {
  SlamSystemOptions slam_options = options_.slam;
  SessionWiring wiring;
  if (mode == SessionMode::kLocalize) {
    // Tracks in the stored maps of its own rig and changes nothing: no lease,
    // no keyframes, no loop closing or merging.
    slam_options.tracker.localization_only = true;
    slam_options.relocalization = true;
    slam_options.loop_closing = false;
    slam_options.live_merging = false;
    wiring.may_enter_map = [this, cameras = rig.cameras](MapId map) { return rigs_.cameras_match(cameras, map); };
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
  // A session that is not real-time (no max_lag_s: an upload, a stream sent as
  // fast as the server answers) waits for its local mapping at each keyframe,
  // as an offline run does: with the background niced, its tracking would
  // otherwise outrun a starved mapping. A real-time one is served first and
  // never waits. Settings that set the wait keep theirs.
  if (!real_time && slam_options.tracker.max_mapping_wait_ms == 0.0)
    slam_options.tracker.max_mapping_wait_ms = TrackerOptions::kLongestMappingWaitMs;
  if (real_time) slam_options.max_maps_wait_ms = options_.max_maps_wait_ms;
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
  const LoadedSettings loaded = load_request_settings(request.settings, config_dir());
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

  const SessionId id = sessions_.reserve_id();
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
    slam = make_slam_system(id, rig, monocular_settings(loaded.settings, sensor), mode, request.max_lag_s.has_value());
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
    slam = make_slam_system(id, rig, loaded.settings, mode, request.max_lag_s.has_value());
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
  sessions_.add_live(id, live, start);
  if (mode == SessionMode::kMap && replicas_)
    replicas_->begin_session_work(id,
                                  StoredMerge{0, start.settings, start.first_keyframe, start.inertial, rig.monocular});
  // The checkpoint thread reads the frames through its own reference.
  checkpointer_->add_session(CheckpointSession{info, [live](std::size_t first) { return live->anchors_from(first); },
                                               [live] { return live->record(); }});
  metrics_.session_created();
  log_info("session " + std::to_string(id) + " started (" + info.name + ", config " + loaded.label + ")");
  return id;
}

std::shared_ptr<LiveSession> AtlasService::session(SessionId id) const { return sessions_.get(id); }

std::vector<std::shared_ptr<LiveSession>> AtlasService::sessions() const { return sessions_.all(); }

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
  return mappings_.for_rig(rig, [&](const std::shared_ptr<SerialWorker>& loop_worker) {
    LoopCloserWiring wiring;
    wiring.shared_worker = loop_worker;
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
    return std::make_shared<MappingWorkers>(atlas_, cam, options, std::move(wiring));
  });
}

std::vector<MapId> AtlasService::end_session_storage(SessionId id) {
  const std::vector<MapId> held = leases_.held_by(id);
  const auto live = session(id);
  const MapRig rig = sessions_.mapping_rig(id);
  if (live->mode() == SessionMode::kMap)
    for (const MapId map : held) rigs_.record(map, rig);
  leases_.release_all(id);
  // The local mapping of maps nobody maps now ends (its thread goes); the
  // merging worker may take those maps from here on.
  if (const auto mapping = mappings_.find(rig))
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
    if (out.jump_m) metrics_.live_pose_jump(*out.jump_m);
  } catch (const ServiceError& e) {
    if (e.code() == "session_failed") {
      end_session_storage(id);
      end_session_work(id);
    }
    throw;
  } catch (const DataError&) {
    metrics_.frame_rejected();
    throw;
  }
  if (reply.skipped) {
    metrics_.frame_skipped();
    return reply;  // nothing tracked: the leases and the checkpoints stay as they are
  }
  // A frame answered maps_busy was not tracked either, but its time in the
  // server (the bound) counts in the latency figures.
  if (reply.result.maps_busy) metrics_.frame_maps_busy();
  // A localisation holds no lease: it changes nothing, any number share a map.
  if (live->mode() != SessionMode::kLocalize && !reply.result.maps_busy) {
    leases_.settle(id, reply.result.tracked ? std::optional<MapId>(reply.result.map) : std::nullopt);
    if (reply.result.tracked) {
      // Known to be of this rig from its first frame: other sessions may enter it.
      // (Its rig is looked up only for a map not recorded yet: not on every frame.)
      if (!rigs_.known(reply.result.map)) rigs_.record(reply.result.map, sessions_.mapping_rig(id));
    }
  }
  if (reply.result.keyframe) checkpointer_->notify_keyframe(id, reply.result.keyframe_id);
  const double request_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - started).count();
  live->note_request(timing.decode_ms, request_ms);
  metrics_.frame_done(reply.tracking_ms, request_ms);
  return reply;
}

std::size_t AtlasService::add_imu(SessionId id, const std::vector<ImuSample>& samples) {
  return session(id)->add_imu(samples);
}

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

void AtlasService::end_session_work(SessionId id) {
  if (replicas_) replicas_->end_session_work(id);
}

void AtlasService::shutdown() {
  if (!sessions_.stop()) return;  // no new session; the idle-expiry thread has ended
  if (replicas_) replicas_->stop();
  const std::vector<std::shared_ptr<LiveSession>> live = sessions_.active();
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
  // Every session has finished above: the mappings finish (a running global
  // adjustment is waited for), then the loop-closing thread stops.
  mappings_.finish();
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
