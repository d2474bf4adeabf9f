#pragma once
// Upload jobs as a queue that every replica of a shared (PostgreSQL) atlas
// takes from (schema/012_shared_jobs, docs/scaling.md "Replicas"). The
// replica that received an upload adds its job (its extracted folder, in the
// work folder the replicas share, and its session request); a free worker of
// any replica claims the oldest waiting job with FOR UPDATE SKIP LOCKED (two
// workers never take one job); the jobs of a replica whose lease has passed
// wait again (a running one starts over, in a new session) and an upload it
// was still receiving fails. `upload_jobs` keeps each job's state as on SQLite.
//
// Thread-safe: one connection under a mutex (each call is one short transaction).
#include <cstdint>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "core/common/ids.h"
#include "core/server/atlas_service.h"
#include "core/server/replica_registry.h"

namespace orbatlas {

class PgDb;

struct ClaimedJob {
  JobId id = 0;
  std::filesystem::path folder;
  SessionRequest request;
};

// The session request of a job as stored (JSON), and back (DataError on a malformed one).
std::string session_request_json(const SessionRequest& request);
SessionRequest session_request_from_json(const std::string& text);

class SharedJobQueue {
 public:
  // `registry` must outlive the queue.
  SharedJobQueue(const ReplicaRegistry& registry, std::string location);
  ~SharedJobQueue();
  SharedJobQueue(const SharedJobQueue&) = delete;
  SharedJobQueue& operator=(const SharedJobQueue&) = delete;

  // The job (its upload_jobs row already stored, state queued) waits for a worker.
  void add(JobId id, const std::filesystem::path& folder, const SessionRequest& request);
  // The oldest waiting job, now this replica's; none when nothing waits.
  std::optional<ClaimedJob> claim();
  // The job has ended (done, failed, cancelled): out of the queue.
  void remove(JobId id);
  // The jobs of dead replicas: queued or running ones wait again (state
  // queued), uploads they were receiving fail. Returns how many wait again.
  std::size_t requeue_dead();
  // Jobs waiting for a worker now.
  std::size_t waiting();

 private:
  const ReplicaRegistry& registry_;
  const std::string location_;
  std::mutex db_mutex_;  // a leaf
  std::unique_ptr<PgDb> db_;
};

}  // namespace orbatlas
