#pragma once
// The map server's state, without HTTP (docs/server.md): a facade over its
// parts (docs/architecture.md "The server's parts"): the sessions
// (SessionRegistry), the mapping of each camera rig (RigMappings), the maps'
// rigs (MapRigRegistry), leases, the checkpointer, the merging worker, the
// localisers (LocalizerPool), the replica's threads on a shared atlas
// (ReplicaCoordinator) and the metrics (ServiceMetrics). Every method is
// thread-safe; the HTTP layer (server/http/http_api.h) only parses requests and
// formats replies. Errors are ServiceError (a kind and a code, which the HTTP
// layer maps to a status), DataError (bad input: 422 there) or Error (500).
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "core/map/atlas.h"
#include "core/persistence/atlas_store.h"
#include "core/persistence/database_lock.h"
#include "core/server/atlas_service_options.h"
#include "core/server/live_session.h"
#include "core/server/localizer_pool.h"
#include "core/server/map_leases.h"
#include "core/server/map_merge_worker.h"
#include "core/server/map_ownership.h"
#include "core/server/map_rig_registry.h"
#include "core/server/replica_coordinator.h"
#include "core/server/replica_registry.h"
#include "core/server/request_settings.h"
#include "core/server/rig_mappings.h"
#include "core/server/service_metrics.h"
#include "core/server/service_results.h"
#include "core/server/session_registry.h"
#include "core/vocabulary/vocabulary.h"

namespace orbatlas {

class AtlasService {
 public:
  // Loads the atlas (Error when the database is refused: another vocabulary, a
  // newer schema, not a database) and starts the checkpointer.
  explicit AtlasService(AtlasServiceOptions options);
  ~AtlasService();  // shutdown()
  AtlasService(const AtlasService&) = delete;
  AtlasService& operator=(const AtlasService&) = delete;

  SessionId create_session(const SessionRequest& request);
  // Uploads run sessions that map (check_upload_request; ServiceError 400/404/422).
  void check_upload(const SessionRequest& request) const;
  SensorType request_sensor(const SessionRequest& request) const;  // request_settings.h
  std::shared_ptr<LiveSession> session(SessionId id) const;        // ServiceError 404
  std::vector<std::shared_ptr<LiveSession>> sessions() const;      // by id
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
  // `ended_by`: who ended it when not the client (shown in the status).
  SessionStatus finish_session(SessionId id, const std::string& ended_by = {});
  // The session's frames in their maps' frames (poses follow later corrections).
  SessionTrajectory trajectory(SessionId id) const;

  std::vector<MapSummary> maps() const;
  MapSummary map(MapId id) const;            // ServiceError 404
  MapPointCloud map_points(MapId id) const;  // ServiceError 404
  MergesReport merges() const;               // GET /v1/merges

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
  // GET /v1/replicas, by id (ServiceError kUnavailable when the database cannot be reached).
  std::vector<ReplicaInfo> replicas() const;
  std::filesystem::path config_dir() const;  // where named configs are read (the shipped ones by default)

 private:
  // The constructor's: the maps (those `claimed` writable on a shared atlas), sessions, their rigs.
  void load_atlas(const std::vector<MapId>& claimed);
  // `real_time`: the session set max_lag_s (served first; it never waits for its mapping).
  std::unique_ptr<SessionSlam> make_slam_system(SessionId id, const MapRig& rig, const SlamSettings& settings,
                                                SessionMode mode, bool real_time);
  std::shared_ptr<MappingWorkers> mapping_for(const MapRig& rig, const FrameCamera& cam,
                                              const MappingWorkersOptions& options);
  std::vector<MapId> end_session_storage(SessionId id);  // leases and checkpoints; the maps it held
  void end_session_work(SessionId id);                   // a shared atlas's row of a mapping session
  void submit_merges(SessionId id, const std::vector<MapId>& maps);
  bool rigs_match(MapId source, MapId target) const;                // may the worker merge them?
  bool mapping_rig_matches(const MapRig& rig, MapId target) const;  // may a session of `rig` map there?
  void merged(const MergeRecord& record);                           // on the merging worker's thread
  void merged_live(const LiveMerge& merge);                         // on the loop-closing thread

  const AtlasServiceOptions options_;
  // First: held while anything below may write the database; destroyed last.
  std::unique_ptr<DatabaseLock> db_lock_;
  // This server's row among the database's replicas (after db_lock_, which migrates the schema).
  std::unique_ptr<ReplicaRegistry> replica_;
  // A shared (PostgreSQL) atlas: the maps this replica writes and the merge
  // work finished sessions left; null on SQLite (every map is this server's).
  std::unique_ptr<MapOwnership> ownership_;
  std::unique_ptr<SharedMerges> shared_merges_;
  const Vocabulary vocabulary_;
  Atlas atlas_;
  MapLeases leases_;
  MapRigRegistry rigs_;
  std::unique_ptr<AtlasCheckpointer> checkpointer_;
  // A connection of the request threads (the checkpointer has its own): a new
  // session's row is stored before its id is handed out; ended sessions'
  // trajectories are read from it. store_mutex_ is a leaf.
  mutable std::mutex store_mutex_;
  mutable std::optional<AtlasStore> store_;
  RigMappings mappings_;  // before sessions_: its loop-closing thread outlives them
  SessionRegistry sessions_;
  LocalizerPool localizers_;
  mutable ServiceMetrics metrics_;
  mutable std::mutex live_merges_mutex_;      // a leaf (taken on the loop-closing thread)
  std::vector<LiveMergeRecord> live_merges_;  // the last kMergeHistory
  std::size_t live_merges_total_ = 0;
  std::unique_ptr<MapMergeWorker> merger_;        // null when merging is off
  std::unique_ptr<ReplicaCoordinator> replicas_;  // a shared atlas only
};

}  // namespace orbatlas
