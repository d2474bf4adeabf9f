#pragma once
// The persistent atlas: one database holding an Atlas — maps, keyframes, map
// points, observations, the covisibility graph, spanning tree and loop edges —
// with the sessions that built it and their per-frame trajectories. Blobs are
// Cereal binary (blob_codec.h). The database is an SQLite file (schema/*.sql,
// docs/schema.md), or a PostgreSQL database (schema/NNN_name/postgres.sql) through
// the same row code (sql_connection.h).
//
// One store is one connection, for one thread at a time. Saving reads the atlas
// through its snapshots; it is exact when no other thread edits the atlas
// meanwhile (pause local mapping), and otherwise consistent per object.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "core/map/atlas.h"
#include "core/persistence/job_rows.h"
#include "core/persistence/session_record.h"
#include "core/persistence/session_info.h"
#include "core/persistence/sql_connection.h"
#include "core/map/frame_anchor.h"
#include "core/vocabulary/vocabulary.h"

namespace orbatlas {

struct AtlasSaveOptions {
  // The session each keyframe was made in (KeyFrame does not record it). A
  // keyframe not listed keeps the session stored for it by an earlier save.
  std::unordered_map<KeyframeId, SessionId> keyframe_sessions;
};

struct AtlasLoadReport {
  std::size_t maps = 0, keyframes = 0, map_points = 0, observations = 0;
  std::size_t covisibility_links = 0, loop_edges = 0, inertial_links = 0, imu_states = 0;
  std::size_t culled_keyframes = 0;                             // anchors restored for Map::keyframe_pose
  std::unordered_map<KeyframeId, SessionId> keyframe_sessions;  // keyframes with a stored session
};

class AtlasStore {
 public:
  // Creates the database, or opens one and brings its schema up to date. Before
  // anything is written, refuses (DataError, file untouched) a file that is not
  // an SQLite database, an SQLite database that is not an atlas, a schema newer
  // than this build, and an atlas built with another vocabulary (hash differs).
  // A `path` that is a postgresql:// or postgres:// URI (atlas_location.h)
  // opens that PostgreSQL database instead (open_postgres; a malformed URI: Error).
  static AtlasStore open(const std::filesystem::path& path, const std::string& vocabulary_hash);
  // The same on PostgreSQL (a libpq connection string or postgresql:// URI):
  // refuses (DataError, nothing written) a database holding other tables, a
  // newer schema, and another vocabulary; then migrates (schema/NNN_name/postgres.sql) and
  // creates the atlas row if missing.
  static AtlasStore open_postgres(const std::string& conninfo, const std::string& vocabulary_hash);

  AtlasStore(AtlasStore&&) noexcept = default;
  AtlasStore& operator=(AtlasStore&&) noexcept = default;

  SqlDialect dialect() const { return db_->dialect(); }
  // The database, for messages: the SQLite file's path or "postgresql host:port/db".
  const std::string& location() const { return db_->description(); }
  const std::string& vocabulary_hash() const { return vocabulary_hash_; }
  TimestampNs created_ns() const { return created_ns_; }
  int schema_version();  // SQLite: PRAGMA user_version; PostgreSQL: schema_migrations' largest
  // atlas.checkpoint_seq: incremented by every committed save_atlas or checkpoint.
  std::int64_t checkpoint_sequence();

  // --- the atlas ---
  // In one transaction: every map of the atlas replaces what was stored for that
  // map id (maps stored earlier but no longer in the atlas are kept); the id
  // allocator's next ids and the active map are recorded, and the checkpoint
  // sequence number goes up by one. Culled map points are not stored; culled
  // keyframes only as the anchor Map::keyframe_pose chains through. A link to an
  // object outside the saved snapshot (culled meanwhile) is left out.
  void save_atlas(const Atlas& atlas, const AtlasSaveOptions& options = {});
  // Recreates every stored map in `atlas`, which must hold no map yet, with the
  // stored ids; the atlas's id allocator continues above every stored id (and
  // above the ids the saved atlas had already handed out). BoW vectors are
  // recomputed with `vocabulary` (it must have the store's hash), or left empty
  // when it is null; feature grids are rebuilt; culled keyframes' anchors are
  // restored (Map::keyframe_pose resolves them as before). Throws DataError on inconsistent
  // stored data; the atlas may then hold part of it and should be discarded.
  AtlasLoadReport load_atlas(Atlas& atlas, const Vocabulary* vocabulary);
  // One stored map as the database has it now, read into a map of `atlas`'s
  // that is not in it yet (Atlas::detached_map; put it in with replace_map).
  // Null when the database has no such map. Throws as load_atlas.
  std::shared_ptr<Map> load_map(const Atlas& atlas, MapId id, const Vocabulary* vocabulary);
  std::vector<MapId> stored_map_ids();

  // --- sessions and their trajectories ---
  // Inserts or replaces the session row and its cameras (its trajectory and
  // keyframe references stay).
  void save_session(const SessionInfo& session);
  std::optional<SessionInfo> load_session(SessionId id);
  std::vector<SessionInfo> load_sessions();  // by id
  // Replaces the session's stored trajectory (the session must be stored).
  // Timestamps must be distinct. References may name keyframes culled since.
  void save_trajectory(SessionId session, const std::vector<FrameAnchor>& anchors);
  std::vector<FrameAnchor> load_trajectory(SessionId session);  // by timestamp
  // What each session did as its last checkpoint stored it (session_record.h);
  // sessions stored before schema 16 have none.
  void save_session_record(SessionId session, const SessionRecord& record);
  std::map<SessionId, SessionRecord> load_session_records() { return read_session_records(*db_); }

  // --- upload jobs (job_rows.h) ---
  void save_job(const StoredJob& job) { write_job(*db_, job); }
  std::vector<StoredJob> load_jobs() { return read_jobs(*db_); }
  std::optional<StoredJob> load_job(std::uint64_t id) { return read_job(*db_, id); }

 private:
  friend class AtlasCheckpointWriter;  // writes through this connection, in its own transactions

  explicit AtlasStore(std::unique_ptr<SqlConnection> db) : db_(std::move(db)) {}
  void read_metadata();

  std::unique_ptr<SqlConnection> db_;  // never null
  std::string vocabulary_hash_;
  TimestampNs created_ns_ = 0;
};

}  // namespace orbatlas
