#pragma once
// Incremental checkpoints of a live atlas into its database, on a thread of
// their own with a connection of their own. Tracking / local mapping call
// notify_keyframe() (never blocks on I/O); every N keyframes or T seconds the
// worker writes one transaction with the rows that changed since the last
// commit (AtlasCheckpointWriter). A failed checkpoint (I/O error, disk full,
// database locked) does not stop anything: it is counted, logged, the file keeps
// the last committed state, and the next checkpoint writes everything changed
// since then. See docs/schema.md for what a checkpoint writes and guarantees.
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "core/common/sample_summary.h"
#include "core/persistence/atlas_checkpoint_writer.h"

namespace orbatlas {

struct CheckpointOptions {
  std::size_t every_keyframes = 10;  // checkpoint after this many notify_keyframe(); 0: never for that reason
  double every_seconds = 5.0;        // and at the latest this long after the previous one; <= 0: no timer
  // The checkpoint thread's nice value (0..19, thread_priority.h): a map
  // server gives it its background threads' value, so that writing the
  // database does not compete with tracking for the cores.
  int worker_nice = 0;
  // Called on the checkpoint thread just before a checkpoint opens its write
  // transaction (instrumentation; the crash-safety test marks it in a pipe).
  std::function<void()> before_transaction;
  // Several writers of one database (replicas): which maps this one
  // writes, asked inside each checkpoint's transaction (atlas_checkpoint_writer.h).
  // Unset: every map.
  WritableMaps writable_maps;
  // Told inside each checkpoint's transaction which maps it changed (unset: nobody).
  MapsChanged maps_changed;

  // Throws Error naming the first value out of range.
  void check() const;
};

struct CheckpointStats {
  std::uint64_t checkpoints = 0;  // completed: committed, or nothing to write
  std::uint64_t commits = 0;
  std::uint64_t failures = 0;
  std::int64_t sequence = 0;  // atlas.checkpoint_seq of the last commit (0 before)
  RowCounts last_rows;        // of the last completed checkpoint
  RowCounts total_rows;
  SampleSummary wall_ms;     // of the completed checkpoints
  double last_ms = 0.0;      // of the last completed checkpoint
  std::string last_error;    // of the last failure; empty when none
  bool last_failed = false;  // the latest checkpoint failed (the final one, after stop())
};

class AtlasCheckpointer {
 public:
  // Opens (or creates) the database on the calling thread, so that a refused
  // file throws here (AtlasStore::open), then starts the worker. `path` is the
  // SQLite file or a postgresql:// URI (atlas_location.h). The checkpoint
  // connection uses synchronous = NORMAL (PostgreSQL: synchronous_commit = off;
  // the final checkpoint FULL / on). `atlas` must outlive the checkpointer.
  AtlasCheckpointer(const Atlas& atlas, const std::filesystem::path& path, const std::string& vocabulary_hash,
                    CheckpointOptions options = {}, std::optional<CheckpointSession> session = std::nullopt);
  ~AtlasCheckpointer();  // stop()
  AtlasCheckpointer(const AtlasCheckpointer&) = delete;
  AtlasCheckpointer& operator=(const AtlasCheckpointer&) = delete;

  // From any thread: counts a keyframe and wakes the worker when enough have
  // come. Takes the worker's mutex only for that wake-up, never across I/O.
  void notify_keyframe();
  // The same, recording which session made the keyframe (several sessions).
  void notify_keyframe(SessionId session, KeyframeId keyframe);
  // From any thread: the next checkpoints write this session's row and
  // trajectory; `session.trajectory` is called on the checkpoint thread until
  // the checkpoint after end_session(id) has succeeded (let it own what it reads).
  void add_session(CheckpointSession session);
  void end_session(SessionId id);
  // Waits until a checkpoint that started after this call has finished. True
  // when it succeeded (committed, or found nothing changed), false when it
  // failed (see stats) or after stop().
  bool checkpoint_now();
  // A final, durable checkpoint, then the worker ends. Idempotent.
  void stop();

  CheckpointStats stats() const;
  const std::filesystem::path& path() const { return path_; }

 private:
  void run();
  // Hands the queued session requests to the writer (worker thread, under mutex_).
  void drain_requests();
  // One checkpoint with every failure caught; updates the stats.
  bool checkpoint_once(bool final);

  const std::filesystem::path path_;
  const CheckpointOptions options_;
  AtlasCheckpointWriter writer_;  // used by the worker only (after construction)
  std::atomic<std::size_t> pending_keyframes_{0};

  mutable std::mutex mutex_;  // guards everything below; never held during a checkpoint
  std::condition_variable wake_;
  std::condition_variable done_;
  bool stopping_ = false;
  bool finished_ = false;        // the worker has ended
  std::uint64_t requested_ = 0;  // checkpoint_now tickets handed out
  std::uint64_t served_ = 0;     // tickets whose checkpoint has finished
  std::uint64_t served_ok_ = 0;  // tickets whose checkpoint succeeded
  CheckpointStats stats_;
  // Requests for the writer, handed over by the worker before each checkpoint.
  std::vector<CheckpointSession> added_sessions_;
  std::vector<SessionId> ended_sessions_;
  std::vector<std::pair<KeyframeId, SessionId>> attributions_;

  std::mutex join_mutex_;  // stop() from several threads
  std::thread worker_;     // last: started once everything above exists
};

}  // namespace orbatlas
