#pragma once
// One connection's checkpoints of an atlas and of the trajectories of the
// sessions working on it (one for `orbatlas run`, several in the server).
// Each checkpoint is one write transaction holding only the rows that are new or
// changed since this writer's last commit, and deleting the rows of objects
// culled since; it is told apart by the content hashes of the rows last
// committed (atlas_rows.h), kept here and replaced only after COMMIT succeeded.
// The first checkpoint rewrites every map of the atlas, as save_atlas does: the
// writer does not know yet what the file holds. It assumes that nobody else
// writes the atlas's maps into the file meanwhile.
//
// Several writers of one database (replicas) each write their own
// maps: `writable_maps` (set_writable_maps) says, inside each checkpoint's
// transaction, which maps this writer may write now; the rows of the others are
// neither written nor deleted. A map it writes for the first time (or again
// after it could not) is rewritten whole, as every map is by the first
// checkpoint.
//
// Not thread-safe: AtlasCheckpointer runs one on its own thread.
#include <functional>
#include <unordered_map>
#include <unordered_set>
#include <optional>
#include <vector>

#include "core/map/atlas.h"
#include "core/map/frame_anchor.h"
#include "core/persistence/atlas_row_sync.h"
#include "core/persistence/atlas_rows.h"
#include "core/persistence/atlas_store.h"
#include "core/persistence/session_info.h"
#include "core/persistence/session_record.h"

namespace orbatlas {

struct CheckpointSession {
  SessionInfo info;  // written by the first checkpoint
  // The session's frames from the `first`-th on (0: all of them), in time
  // order. Frames only ever follow: one returned once is never changed (an
  // anchor follows its keyframe's corrections by itself), so each checkpoint
  // asks for the frames after those it has taken and holds none of them.
  // Called on the checkpoint thread, so it must be safe to call while tracking
  // runs (e.g. a copy under a lock).
  std::function<std::vector<FrameAnchor>(std::size_t first)> trajectory;
  // What the session has done so far (its counts, how it ended), written with
  // its frames when it changed; called on the checkpoint thread as `trajectory`
  // is. Unset: no record.
  std::function<SessionRecord()> record;
};

// Of `candidates` (the atlas's maps, and the maps merged away since it was
// loaded), the maps this writer may write in the checkpoint whose transaction
// is open on `db` (e.g. those whose ownership rows it could lock). `gone`: the
// candidates this checkpoint deletes, merged away as its snapshot of the atlas
// saw it (a map merged away after the snapshot is still written, as it was).
using WritableMaps = std::function<std::unordered_set<MapId>(SqlConnection& db, const std::vector<MapId>& candidates,
                                                             const std::unordered_set<MapId>& gone)>;

// The maps whose rows the checkpoint whose transaction is open on `db` has
// changed (replicas of one database: a version the others watch).
using MapsChanged = std::function<void(SqlConnection& db, const std::vector<MapId>& maps)>;

struct CheckpointResult {
  bool committed = false;     // false: nothing had changed and nothing was written
  bool full = false;          // the first checkpoint: every map rewritten
  RowCounts rows;             // atlas rows, trajectory rows, the session row, the atlas row
  std::int64_t sequence = 0;  // atlas.checkpoint_seq after the commit (0 when nothing was written)
};

class AtlasCheckpointWriter {
 public:
  // `atlas` must outlive the writer. Keyframes with an id the atlas had not
  // handed out yet at construction are recorded as made in `session` (unless
  // attributed to another session).
  AtlasCheckpointWriter(const Atlas& atlas, AtlasStore store, std::optional<CheckpointSession> session);

  // A session whose row and trajectory the next checkpoints write (its
  // trajectory function must stay callable until it has ended). Throws when a
  // session with that id is already checkpointed.
  void add_session(CheckpointSession session);
  // The next successful checkpoint writes the session's trajectory one last
  // time, then the writer forgets it (and its trajectory function).
  void end_session(SessionId id);
  // Records that a keyframe was made by a session (several sessions at once).
  void attribute_keyframe(KeyframeId keyframe, SessionId session);
  // Several writers of one database: only these maps are written (unset: every map).
  void set_writable_maps(WritableMaps writable) { writable_maps_ = std::move(writable); }
  // Told, inside each checkpoint's transaction, which maps it changed (unset: nobody).
  void set_maps_changed(MapsChanged changed) { maps_changed_ = std::move(changed); }
  // The maps the last committed checkpoint wrote (what the database holds of them is committed_).
  const std::unordered_set<MapId>& written_maps() const { return written_maps_; }
  std::size_t session_count() const { return sessions_.size(); }

  // Throws Error / DataError on any failure; the database then holds the last
  // committed checkpoint and the next call writes everything changed since.
  // `before_transaction` runs just before the write transaction begins.
  CheckpointResult checkpoint(const std::function<void()>& before_transaction = {});

  // PRAGMA synchronous: FULL (a commit survives power loss) or NORMAL (a commit
  // survives a crash of the process; see docs/schema.md). On PostgreSQL:
  // synchronous_commit on / off (off: a server crash may lose the last commits).
  void set_durable(bool durable);

  AtlasStore& store() { return store_; }
  // Frames left out of a checkpoint so far because their reference keyframe
  // was not in its snapshot. The next checkpoints try them again; after
  // kDeferrals tries they are left out for good (dropped_frames): their
  // keyframe went with a reset or a merge, and a frame stored without it would
  // resolve through whatever keyframe later gets that id.
  std::size_t deferred_frames() const { return deferred_frames_; }
  std::size_t dropped_frames() const { return dropped_frames_; }
  static constexpr int kDeferrals = 3;

 private:
  struct PendingFrame {
    FrameAnchor anchor;
    int tries = 0;  // checkpoints that left it out
  };

  // A session's frames not yet in the file: those taken from its source and
  // deferred by earlier checkpoints, then the source's new ones.
  struct NewFrames {
    std::vector<PendingFrame> frames;
    std::size_t taken = 0;              // the source's frames taken so far, these included
    std::optional<TimestampNs> last_t;  // the newest of them
  };

  struct SessionState {
    CheckpointSession session;
    bool written = false;                         // its row is in the file
    bool ending = false;                          // forget it after the next successful checkpoint
    std::size_t taken = 0;                        // frames taken from its source (stored, deferred or dropped)
    std::optional<TimestampNs> last_t;            // the newest of them
    std::vector<PendingFrame> deferred;           // taken, not yet stored
    std::optional<SessionRecord> written_record;  // its record as the file has it
  };

  NewFrames new_frames(const SessionState& state) const;
  std::optional<SessionId> session_of(KeyframeId id) const;
  // Splits `pending` into the frames whose reference keyframe is in
  // `stored_keyframes` (returned) and those deferred again (left in
  // `pending`; those deferred kDeferrals times are dropped).
  std::vector<FrameAnchor> take_storable(std::vector<PendingFrame>& pending,
                                         const std::unordered_set<KeyframeId>& stored_keyframes);

  const Atlas& atlas_;
  AtlasStore store_;
  std::vector<SessionState> sessions_;
  std::optional<SessionId> claims_new_keyframes_;  // the constructor's session
  KeyframeId first_session_keyframe_ = 0;
  std::unordered_map<KeyframeId, SessionId> keyframe_sessions_;  // attribute_keyframe
  std::unordered_map<KeyframeId, SessionId> stored_sessions_;    // read by the first checkpoint

  bool has_committed_ = false;
  AtlasRows committed_;  // what the file holds for the maps of written_maps_ (objects dropped)
  WritableMaps writable_maps_;
  MapsChanged maps_changed_;
  std::unordered_map<MapId, std::uint64_t> committed_digests_;  // map_digests of committed_ (with maps_changed_)
  std::unordered_set<MapId> written_maps_;                      // maps whose rows in committed_ are the file's
  std::unordered_set<MapId> deleted_maps_;                      // maps merged away whose rows this writer deleted
  std::size_t deferred_frames_ = 0;
  std::size_t dropped_frames_ = 0;
};

}  // namespace orbatlas
