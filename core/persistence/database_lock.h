#pragma once
// One writer per atlas database, and a record of how the last one ended.
//
// A process that writes an atlas (orbatlas-server, orbatlas run --atlas) holds
// an exclusive flock on "<db>.lock" for its whole life: a second one on the
// same file fails at start with the first one's pid instead of interleaving
// checkpoints. The file also says whether its last holder stopped cleanly
// ("stopped", written after the final checkpoint) or died ("running" left
// behind: SIGKILL, a crash, power loss). After such a death the ids the dead
// process handed out after its last checkpoint are unknown, so the atlas's id
// counters are moved past them (kIdGapAfterCrash): an id a client or a log saw
// is never given to a different object.
#include <cstdint>
#include <filesystem>
#include <string>

namespace orbatlas {

class Atlas;
class PgWriterLock;

// Larger than any number of ids one process can hand out between two
// checkpoints (2^32 keyframes: one per frame at 1 kHz for 48 days; 2^40 map
// points: 10,000 a second for 3 years), small enough that millions of crashes
// stay below the 2^63 the database's integer columns hold.
inline constexpr std::uint64_t kKeyframeIdGapAfterCrash = std::uint64_t{1} << 32;
inline constexpr std::uint64_t kMapPointIdGapAfterCrash = std::uint64_t{1} << 40;
inline constexpr std::uint64_t kMapIdGapAfterCrash = std::uint64_t{1} << 24;

// kShared: orbatlas-server replicas of one PostgreSQL atlas, each
// writing the maps it owns (map ownership, core/server/map_ownership.h), hold
// the lock together, and a single writer (orbatlas run) waits for them all;
// they need no crash record (every replica hands out ids of its own ranges).
// On SQLite, kShared is kExclusive: an SQLite atlas has one writer.
enum class DatabaseLockMode { kExclusive, kShared };

class DatabaseLock {
 public:
  // Takes the lock (Error naming the holder when another process has it).
  // `db`: the SQLite file, or a postgresql:// URI.
  explicit DatabaseLock(const std::filesystem::path& db, DatabaseLockMode mode = DatabaseLockMode::kExclusive);
  ~DatabaseLock();  // releases the lock; the file keeps saying "running" unless mark_stopped()
  DatabaseLock(const DatabaseLock&) = delete;
  DatabaseLock& operator=(const DatabaseLock&) = delete;

  // True when the previous holder died without mark_stopped() (never for a new database).
  bool previous_holder_crashed() const { return previous_crashed_; }
  // After the final checkpoint: the next holder finds a clean stop.
  void mark_stopped();

 private:
  void write_state(const std::string& text);

  std::filesystem::path path_;
  int fd_ = -1;
  std::unique_ptr<PgWriterLock> pg_;  // PostgreSQL: instead of the file
  bool previous_crashed_ = false;
};

// Moves the atlas's id counters past anything a crashed writer may have handed
// out (call after loading, before any new id).
void skip_ids_after_crash(Atlas& atlas);

}  // namespace orbatlas
