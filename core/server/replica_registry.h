#pragma once
// The orbatlas-server replicas that share one atlas database
// (docs/scaling.md "Replicas"). On PostgreSQL each replica adds a row to
// `replicas` (schema/010_replicas) when it starts, renews its lease from a
// thread of its own while it runs, and marks the row stopped when it stops
// cleanly. A replica whose lease has passed is dead (SIGKILL, a crash, a lost
// network): the other replicas see it in replicas() as not alive, which is
// what taking over its maps and jobs will build on. Leases are kept in the
// database's clock, so the hosts' clocks never have to agree.
//
// A lease that has passed is never renewed: a replica that could not reach the
// database for longer than its lease (or was stopped that long) finds its
// lease lost (lease_lost(), logged), since others may already have taken over
// what it held. An SQLite atlas has one server: it is its only replica
// (id 1, no lease).
//
// Thread-safe. The renewal thread waits on a condition variable between
// renewals (a third of the lease), so stopping is immediate.
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "core/common/timestamp.h"

namespace orbatlas {

class PgDb;

// The ids a replica of a shared atlas hands out: ranges of its own, from its
// replica id (ids of kind K in [id << shift_K, (id + 1) << shift_K)), so that
// replicas of one database never give one id to two objects. A restarted
// server is a new replica with new ranges, which also steps over whatever a
// killed one handed out after its last checkpoint (SQLite's id gap after a crash).
inline constexpr int kReplicaKeyframeIdShift = 32;                            // 4 billion keyframes per replica
inline constexpr int kReplicaMapPointIdShift = 40;                            // 1 trillion map points
inline constexpr int kReplicaMapIdShift = 24;                                 // 16 million maps, sessions, upload jobs
inline constexpr std::uint64_t kMaxReplicaId = (std::uint64_t{1} << 23) - 1;  // map point ids below 2^63
struct ReplicaIdRange {
  std::uint64_t begin = 0, end = 0;
  bool contains(std::uint64_t id) const { return id >= begin && id < end; }
};
inline ReplicaIdRange replica_id_range(std::uint64_t replica, int shift) {
  return {replica << shift, (replica + 1) << shift};
}
// The replica whose range holds `id` (ids of kind `shift`).
inline std::uint64_t replica_of_id(std::uint64_t id, int shift) { return id >> shift; }

struct ReplicaOptions {
  std::string url;        // where this replica's HTTP API is reached, for the others ('': not said yet)
  double lease_s = 10.0;  // a replica not heard of for this long is dead

  // Throws Error naming the first value out of range.
  void check() const;
};

struct ReplicaInfo {
  std::uint64_t id = 0;
  std::string holder;  // "pid N on host H"
  std::string url;
  TimestampNs started_ns = 0;
  std::string state;   // running, stopped
  bool alive = false;  // running, and its lease has not passed
  // Seconds until its lease passes (negative: passed); none on SQLite.
  std::optional<double> lease_left_s;
  bool self = false;  // the replica that answered
};

class ReplicaRegistry {
 public:
  // `db`: the atlas's SQLite file or postgresql:// URI (its schema already
  // migrated: DatabaseLock does that). On PostgreSQL: registers this replica
  // (Error when the database cannot be reached) and starts renewing its lease.
  ReplicaRegistry(const std::filesystem::path& db, ReplicaOptions options);
  ~ReplicaRegistry();  // stop()
  ReplicaRegistry(const ReplicaRegistry&) = delete;
  ReplicaRegistry& operator=(const ReplicaRegistry&) = delete;

  std::uint64_t id() const { return id_; }
  bool shared() const { return shared_; }  // PostgreSQL: replicas may be several
  const ReplicaOptions& options() const { return options_; }
  // Where this replica's HTTP API is reached, once known (the server learns
  // its port after the atlas is loaded). Error when the database cannot be reached.
  void set_url(const std::string& url);
  std::string url() const;
  // Every replica the database knows of, by id (SQLite: this one). Error when
  // the database cannot be reached.
  std::vector<ReplicaInfo> replicas() const;

  bool lease_lost() const { return lease_lost_; }
  std::uint64_t renewals() const { return renewals_; }
  std::uint64_t failed_renewals() const { return failed_renewals_; }

  // Stops renewing and marks this replica stopped (it is then not alive for
  // the others). Idempotent; errors are logged, not thrown.
  void stop();

 private:
  void renew_until_stopped();
  // One renewal on its own connection (reconnecting after a failure).
  void renew_once();

  const ReplicaOptions options_;
  mutable std::mutex url_mutex_;  // guards url_
  std::string url_;
  const std::string location_;  // the database, as given
  const bool shared_;
  std::uint64_t id_ = 1;
  TimestampNs started_ns_ = 0;
  std::string holder_;

  mutable std::mutex query_mutex_;          // guards query_db_
  mutable std::unique_ptr<PgDb> query_db_;  // replicas(); reconnected after a failure
  std::unique_ptr<PgDb> renew_db_;          // the renewal thread's; null after a failure

  std::mutex stop_mutex_;  // guards stopping_
  std::condition_variable stop_cv_;
  bool stopping_ = false;
  std::atomic<bool> stopped_{false};
  std::atomic<bool> lease_lost_{false};
  std::atomic<std::uint64_t> renewals_{0}, failed_renewals_{0};
  std::thread renewer_;  // last: started once everything above exists
};

}  // namespace orbatlas
