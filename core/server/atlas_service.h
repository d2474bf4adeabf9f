#pragma once
// The map server's state, without HTTP (docs/server.md): the atlas loaded from
// its database, the vocabulary, the live and stored sessions, map leases, the
// incremental checkpointer and the localisation service. Every method is
// thread-safe; the HTTP layer (server/http/http_api.h) only parses requests and
// formats replies. Errors are ServiceError (a kind and a code, which the HTTP
// layer maps to a status), DataError (bad input: 422 there) or Error (500).
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <thread>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "core/geometry/trajectory.h"
#include "core/map/atlas.h"
#include "core/persistence/atlas_checkpointer.h"
#include "core/persistence/atlas_store.h"
#include "core/persistence/database_lock.h"
#include "core/persistence/map_rigs.h"
#include "core/server/metrics_registry.h"
#include "core/server/live_session.h"
#include "core/server/map_leases.h"
#include "core/server/map_merge_worker.h"
#include "core/server/map_ownership.h"
#include "core/server/replica_registry.h"
#include "core/server/service_results.h"
#include "core/server/session_request.h"
#include "core/server/session_rules.h"
#include "core/slam/slam_system.h"
#include "core/vocabulary/vocabulary.h"

namespace orbatlas {

struct StoredMerge;

class SharedMerges;

// Request limits checked at the edge (400 beyond them).
inline constexpr std::size_t kMaxSettingsBytes = 1 << 20;  // a settings_yaml text

struct AtlasServiceOptions {
  std::filesystem::path db;          // created when missing
  std::filesystem::path config_dir;  // named configs: <config_dir>/<name>.yaml; empty: the shipped ones
  std::filesystem::path vocabulary;  // empty: the shipped one
  CheckpointOptions checkpoints;
  SlamSystemOptions slam;
  std::size_t max_live_sessions = 8;
  // A live session without a frame or IMU batch for this long is finished by
  // the server (stored like any other, status "ended_by": "idle_timeout"), so
  // abandoned sessions cannot hold the live-session slots. <= 0: never.
  double idle_timeout_s = 300.0;
  // A stereo mapping session that ends in a map other sessions mapped too
  // waits (in its finish) at most this long for a global BA of that map when
  // the map grew since its last one (SlamSystemOptions::shared_map_finish_wait_s),
  // so the trajectory read after the finish has it. 0: no such adjustment.
  double finish_refinement_wait_s = 15.0;
  // A finished session's maps are handed to the server-wide merging worker,
  // which merges them into a map of the atlas they share a place with.
  bool merge_maps = true;
  // With merge_maps: a live session's map is also merged WHILE it runs, when
  // place recognition finds a free map of the atlas made with the same camera
  // rig that shares a place with it (SlamSystemOptions::live_merging); the
  // session's tracking follows into that map.
  bool live_merging = true;
  // A new session first looks for its place in the free stored maps: found, it
  // tracks in that map's frame from its first frame (TrackerOptions::start_in_stored_map).
  bool start_in_stored_maps = true;
  // Loop closing (place recognition and correction in a session's own map) runs
  // on one server-wide thread for every session, with a queue this long
  // (a full queue skips a keyframe, counted in the session's loop statistics).
  std::size_t loop_queue = 64;
  MapMergeWorkerOptions merging;
  // The nice value (0..19) of every background thread: local mapping, loop
  // closing and its global BAs, map merging, checkpoints (thread_priority.h); above 0 the
  // sessions' tracking is served first on a loaded machine, mapping takes the
  // cores' rest. For live sessions at the camera's rate, 10 measured best: four
  // sessions on two cores were late 4.7 % of the time at 0, 1.4-1.6 % at 10
  // (CHANGELOG.md, 2026-11-26). 0 by default because a stream sent as
  // fast as the server takes it (an upload, a test) keeps tracking busy and
  // starves mapping at 10: a single camera's map then ended with scale errors of
  // 0.13-0.46 % instead of 0-0.18 % (ServerMerging.TheMergingWorkerMerges...).
  int background_nice = 0;
  // This server as one replica of the atlas's database (replica_registry.h).
  ReplicaOptions replica;

  // Throws Error naming the first value out of range (also of the parts).
  void check() const;
};

// When a frame's request began to be handled and how long its images took to
// decode (the HTTP layer's part), so that its latency is counted whole.
struct FrameRequestTiming {
  std::optional<std::chrono::steady_clock::time_point> started;  // none: when process_frame is called
  double decode_ms = 0.0;
};

struct FrameReply {
  SessionId session = 0;
  TrackResult result;
  double tracking_ms = 0.0;
  bool skipped = false;          // too late (SessionRequest::max_lag_s): not tracked
  std::optional<double> jump_m;  // the pose's jump at a correction of the maps (FrameOutcome::jump_m)
};

struct SessionTrajectory {
  Trajectory poses;                 // the frames that resolve, by time
  std::vector<std::uint64_t> maps;  // the map each is in now (after merges)
  std::size_t frames = 0;           // frames the session tracked
  std::size_t unresolved = 0;       // of them, anchored to a keyframe no map has any more
};

struct LocalizeRequest {
  SettingsSource settings;
  cv::Mat left, right;  // right may be empty: a single image
  std::optional<MapId> map;
};

struct LocalizeReply {
  bool recognised = false;
  MapId map = 0;
  Pose3 T_w_b;
  int inliers = 0;
  std::size_t candidates = 0;
  double ms = 0.0;
};

class AtlasService {
 public:
  // Loads the atlas (Error when the database is refused: another vocabulary, a
  // newer schema, not a database) and starts the checkpointer.
  explicit AtlasService(AtlasServiceOptions options);
  ~AtlasService();  // shutdown()
  AtlasService(const AtlasService&) = delete;
  AtlasService& operator=(const AtlasService&) = delete;

  SessionId create_session(const SessionRequest& request);
  // ServiceError when the settings cannot be used (uploads check before receiving).
  // Uploads run sessions that map (stereo, RGB-D, or a single camera with a
  // mono config): ServiceError 400/404 for settings that cannot be used, 422
  // for a single camera that would only localise (stream it instead).
  void check_upload(const SessionRequest& request) const;
  // The sensor a request's session has (its recording: the TUM RGB-D layout
  // for rgbd, cam0 of an ASL folder for a single camera, else stereo pairs).
  SensorType request_sensor(const SessionRequest& request) const;
  std::shared_ptr<LiveSession> session(SessionId id) const;    // ServiceError 404
  std::vector<std::shared_ptr<LiveSession>> sessions() const;  // by id
  // GET /v1/sessions/{id}: LiveSession::status with `map` the map the session's
  // last frame is in now (a merge may have moved it). ServiceError 404.
  SessionStatus session_status(SessionId id) const;
  // One frame of a live session; `timing`: when its request began and its
  // decoding (the session's request_ms / decode_ms and /metrics' latency).
  FrameReply process_frame(SessionId id, TimestampNs t_ns, const cv::Mat& left, const cv::Mat& right,
                           const FrameRequestTiming& timing = {});
  std::size_t add_imu(SessionId id, const std::vector<ImuSample>& samples);
  // Ends the session and stores it (a durable checkpoint); idempotent for a
  // finished session, ServiceError 409 for a stored one. Returns its status.
  SessionStatus finish_session(SessionId id);
  // The same on the server's behalf: `ended_by` is shown in the status.
  SessionStatus finish_session(SessionId id, const std::string& ended_by);
  // The session's frames in their maps' frames (poses follow later corrections).
  SessionTrajectory trajectory(SessionId id) const;

  std::vector<MapSummary> maps() const;
  MapSummary map(MapId id) const;            // ServiceError 404
  MapPointCloud map_points(MapId id) const;  // ServiceError 404
  // GET /v1/merges: the merging worker's queue and the merges done.
  MergesReport merges() const;

  LocalizeReply localize(const LocalizeRequest& request);
  // The image size a localisation with these settings takes (ServiceError for
  // unusable settings): requests are checked against it before decoding.
  cv::Size localize_image_size(const SettingsSource& settings);

  // The service's Prometheus metrics, brought up to date (the HTTP layer writes them out).
  std::vector<prometheus::MetricFamily> metrics() const;
  HealthReport health() const;
  // Finishes every live session, writes the final durable checkpoint. Idempotent.
  void shutdown();

  Atlas& atlas() { return atlas_; }
  const Atlas& atlas() const { return atlas_; }
  const Vocabulary& vocabulary() const { return vocabulary_; }
  const std::filesystem::path& db_path() const { return options_.db; }
  const ReplicaRegistry& replica() const { return *replica_; }
  // Where this server's API is reached (ReplicaRegistry::set_url).
  void replica_url(const std::string& url) { replica_->set_url(url); }
  // GET /v1/replicas: the replicas of the atlas's database, by id
  // (ServiceError kUnavailable when the database cannot be reached).
  std::vector<ReplicaInfo> replicas() const;
  std::filesystem::path config_dir() const;  // where named configs are read (the shipped ones by default)

 private:
  struct LoadedSettings {
    SlamSettings settings;
    std::string label;  // the config name, or "inline"
  };
  struct LocalizerContext;

  LoadedSettings load_settings(const SettingsSource& source) const;
  std::shared_ptr<LocalizerContext> localizer_for(const SettingsSource& source);
  // A stereo session's SLAM with the server's policies (leases, live merging).
  std::unique_ptr<SessionSlam> make_slam_system(SessionId id, const MapRig& rig, const SlamSettings& settings,
                                                SessionMode mode);
  // The mapping (local mapping per map, loop closing) every mapping session of
  // this camera rig shares; made with the first session's options.
  std::shared_ptr<MappingWorkers> mapping_for(const MapRig& rig, const FrameCamera& cam,
                                              const MappingWorkersOptions& options);
  // Leases and checkpoints after a session ended; returns the maps it held.
  std::vector<MapId> end_session_storage(SessionId id);
  // Live sessions whose last frame was tracked in `map` (lock-free reads of each).
  std::vector<SessionId> sessions_in(MapId map) const;
  // The camera of a merge request made with these settings (ServiceError when unusable).
  std::shared_ptr<const FrameCamera> merge_camera(const SettingsSource& settings);
  // Hands a finished session's maps to the merging worker.
  void submit_merges(SessionId id, const std::vector<MapId>& maps);
  // May two maps be merged (made with one camera rig)?
  // Same cameras (merging by the worker: no session maps either map).
  bool rigs_match(MapId source, MapId target) const;
  // `target` was made with these cameras (localisation reads any such map).
  bool cameras_match(const CameraRig& cameras, MapId target) const;
  // ... and by sessions that fuse their IMU exactly when `rig`'s do (mapping in it).
  bool mapping_rig_matches(const MapRig& rig, MapId target) const;
  // The rig a session maps with (its cameras; whether it fuses its IMU).
  MapRig mapping_rig(SessionId id) const;
  void merged(const MergeRecord& record);  // on the worker thread
  // The idle-session thread: waits for the earliest idle deadline, finishes
  // the sessions past it.
  void finish_idle_sessions();
  void merged_live(const LiveMerge& merge);  // on the loop-closing thread
  // A shared atlas, at start after the load (atlas_service_replicas.cc): ids of
  // this replica's own ranges; the maps claimed before the load may be written.
  void start_as_replica(const std::vector<MapId>& claimed);
  // Puts maps read again from the database in place of this server's copies
  // (or as new ones) and drops `gone`, keeping the keyframe index in step.
  void swap_in_maps(const std::vector<std::shared_ptr<Map>>& fresh, const std::vector<MapId>& gone);
  // A shared atlas (atlas_service_replicas.cc): takes over the maps nobody owns
  // and those of dead replicas, reading them again from the database (and the
  // sessions this server does not know yet); returns the maps taken over.
  std::vector<MapId> take_over_maps();
  // Stored sessions this server does not list yet: those of replicas that
  // stopped or died (or from before replicas) are listed, with their maps'
  // rigs recorded; with `rigs_of_live_replicas`, the rigs of the maps of live
  // replicas' sessions too (they report those sessions themselves). Under
  // nothing; takes mutex_ and rigs_mutex_.
  void load_new_sessions(AtlasStore& store, bool rigs_of_live_replicas);
  // The takeover thread's connection (opened when first needed).
  AtlasStore& replica_store();
  // A shared atlas: reads again the maps other replicas changed (their version
  // in map_owners moved) or made since, and drops those they merged away;
  // returns the maps read. Localisation then sees them as their owners have them.
  std::vector<MapId> refresh_others_maps();
  // The takeover thread: take_over_maps() and refresh_others_maps() every lease, until shutdown.
  void take_over_until_stopped();
  // A shared atlas (atlas_service_merge_work.cc): the merge-work thread, woken
  // by a finished session's merge rows, by the merging worker when it is done
  // with one, and every lease; share_merge_work() until shutdown.
  void share_merge_work_until_stopped();
  // Once: hands the maps other replicas asked for over when nothing works in
  // them here; claims this replica's next merge row when its worker is free;
  // a free worker with nothing of its own asks for a map whose row waited.
  void share_merge_work();
  // A checkpoint, then `map` is `to`'s (false when something works in it here).
  bool hand_over_if_idle(MapId map, std::uint64_t to);
  // A claimed merge row goes to the merging worker (false when it cannot).
  bool submit_stored_merge(const StoredMerge& merge);
  // The merging worker put a claimed row off (its place is in `target`, a map
  // another replica writes or a session holds): ask for `target`, retry later.
  void merge_put_off(MapId source, MapId target);
  void wake_merge_work();
  // A shared atlas's rows of live mapping sessions (SharedMerges::
  // begin_session): kept while the session maps; ended when it finishes or
  // fails (a shutdown leaves them, for another replica to adopt); the
  // sessions of replicas gone are adopted by the takeover thread. A database
  // error is logged, never thrown: the session goes on without its row.
  void begin_session_work(SessionId id, const StoredMerge& request);
  void end_session_work(SessionId id);
  void adopt_gone_sessions_work();

  const AtlasServiceOptions options_;
  // First: held while anything below may write the database; destroyed last.
  std::unique_ptr<DatabaseLock> db_lock_;
  // This server's row among the database's replicas (after db_lock_, which migrates the schema).
  std::unique_ptr<ReplicaRegistry> replica_;
  // A shared (PostgreSQL) atlas: the maps this replica writes; null on SQLite (every map).
  std::unique_ptr<MapOwnership> ownership_;
  // A shared atlas: the merge work finished sessions left (null on SQLite).
  std::unique_ptr<SharedMerges> shared_merges_;
  const Vocabulary vocabulary_;
  Atlas atlas_;
  MapLeases leases_;
  std::unique_ptr<AtlasCheckpointer> checkpointer_;
  // A connection of the request threads (the checkpointer has its own): a new
  // session's row is stored before its id is handed out; ended sessions'
  // trajectories are read from it.
  mutable std::mutex store_mutex_;
  mutable std::optional<AtlasStore> store_;

  // The server-wide loop-closing thread (before sessions_: destroyed after them).
  const std::shared_ptr<SerialWorker> loop_worker_;
  // One mapping per camera rig and IMU use (its options are the first
  // session's: sessions that fuse an IMU need local mapping that initialises
  // it), shared by its mapping sessions (after loop_worker_: destroyed before
  // it). mappings_mutex_ is a leaf.
  struct RigMapping {
    MapRig rig;
    std::shared_ptr<MappingWorkers> workers;
  };
  mutable std::mutex mappings_mutex_;
  std::vector<RigMapping> mappings_;

  mutable std::mutex mutex_;  // guards sessions_, next_session_, shut_down_
  std::map<SessionId, std::shared_ptr<LiveSession>> sessions_;
  struct SessionStart {
    SettingsSource settings;
    KeyframeId first_keyframe = 0;  // keyframe ids from here on are this session's or later ones
    // A mapping session that fuses its IMU: the merging worker's global BAs keep the IMU terms.
    std::optional<GlobalBundleAdjustmentOptions::Inertial> inertial;
    MapRig rig;  // what it maps with
  };
  std::map<SessionId, SessionStart> session_starts_;  // of this run's sessions
  mutable std::mutex live_merges_mutex_;              // a leaf lock (taken on the loop-closing thread)
  std::vector<LiveMergeRecord> live_merges_;          // the last kMergeHistory; guarded by live_merges_mutex_
  std::size_t live_merges_total_ = 0;                 // guarded by live_merges_mutex_
  SessionId next_session_ = 1;
  bool shut_down_ = false;
  std::condition_variable idle_wake_;  // with mutex_: a session was created, or shutdown

  std::mutex localizers_mutex_;
  // One per configuration seen, at most kMaxLocalizers (inline settings vary:
  // an old one is dropped; a request still using it keeps it alive).
  static constexpr std::size_t kMaxLocalizers = 8;
  std::map<std::string, std::shared_ptr<LocalizerContext>> localizers_;

  mutable std::mutex rigs_mutex_;     // a leaf lock (the merging worker asks under the index's lock)
  std::map<MapId, MapRig> map_rigs_;  // the camera rig each map was made with

  std::unique_ptr<MapMergeWorker> merger_;  // null when merging is off
  std::thread idle_thread_;                 // started last in the constructor, joined by shutdown()
  std::condition_variable takeover_wake_;   // with mutex_: shutdown
  // The version of each other replica's map this server has read (the constructor, then the takeover thread only).
  std::map<MapId, std::int64_t> seen_versions_;
  std::optional<AtlasStore> replica_store_;  // the takeover thread's only
  std::thread takeover_thread_;              // a shared atlas only; joined by shutdown()
  // The merge-work thread (a shared atlas only; joined by shutdown()), woken
  // with mutex_ through merge_work_woken_; the merge rows this replica's worker
  // has claimed (merge_work_mutex_, a leaf).
  std::condition_variable merge_work_wake_;
  bool merge_work_woken_ = false;  // guarded by mutex_
  std::mutex merge_work_mutex_;
  std::set<MapId> claimed_merges_;
  std::thread merge_work_thread_;
  // The lease holder of a map being handed over to another replica (no session gets this id).
  static constexpr SessionId kHandOverLease = kInvalidSessionId - 2;

  // GET /metrics: counters counted as things happen, the gauges set when asked.
  mutable MetricsRegistry metrics_;
  mutable std::mutex scrape_mutex_;  // one metrics_text() at a time (totals kept elsewhere are synced)
  prometheus::Counter& sessions_created_ =
      metrics_.counter("orbatlas_sessions_created_total", "Sessions created since the server started.");
  prometheus::Counter& sessions_timed_out_ = metrics_.counter(
      "orbatlas_sessions_timed_out_total", "Live sessions the server finished after their idle timeout.");
  prometheus::Counter& frames_ = metrics_.counter("orbatlas_frames_total", "Frames processed.");
  prometheus::Counter& frames_rejected_ =
      metrics_.counter("orbatlas_frames_rejected_total", "Frames refused as bad input.");
  prometheus::Counter& frames_skipped_ = metrics_.counter(
      "orbatlas_frames_skipped_total", "Frames of real-time sessions skipped for arriving too late (max_lag_s).");
  prometheus::Histogram& tracking_latency_ = metrics_.histogram(
      "orbatlas_tracking_latency_seconds", "Time to track one frame (features included).", latency_buckets_seconds());
  prometheus::Histogram& frame_request_latency_ = metrics_.histogram(
      "orbatlas_frame_request_seconds",
      "A live frame's time in the server, from its request's handling to its reply (decoding and tracking).",
      latency_buckets_seconds());
  prometheus::Histogram& live_pose_jumps_ =
      metrics_.histogram("orbatlas_live_pose_jump_meters",
                         "How far a live session's pose jumped at the first frame after a correction of the maps.",
                         {0.001, 0.003, 0.01, 0.03, 0.1, 0.3, 1.0, 3.0});
  prometheus::Counter& localize_requests_ =
      metrics_.counter("orbatlas_localize_requests_total", "Localisation requests.");
  prometheus::Counter& localize_recognised_ =
      metrics_.counter("orbatlas_localize_recognised_total", "Localisation requests that recognised the place.");
  prometheus::Histogram& localize_latency_ = metrics_.histogram(
      "orbatlas_localize_latency_seconds", "Time to answer a localisation request.", latency_buckets_seconds());
};

}  // namespace orbatlas
