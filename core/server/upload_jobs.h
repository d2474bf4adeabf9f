#pragma once
// Uploaded recordings processed in the background (POST /v1/uploads): the HTTP
// layer extracts the tar of an EuRoC ASL folder into a new folder of the server's
// work folder while it arrives (tar_stream_extractor.h); each job then feeds its
// stereo frames to a new session of the service (as a live client would), finishes
// (stores) the session, and evaluates it when the recording has ground truth.
// `workers` threads take jobs from a bounded queue; a full queue refuses uploads
// (503) instead of piling them on disk.
//
// Jobs are rows of the atlas database (upload_jobs), written at every change of
// state: job ids are never handed out twice, and a job that was queued or
// running when the server died is reported as failed ("interrupted") after the
// restart. The work folder belongs to the server: it is emptied at start, and a
// job only reads the folder it extracted itself.
//
// On a shared (PostgreSQL) atlas the replicas share one queue (shared_job_queue.h):
// `work_dir` must then be one folder all replicas reach at the same path (it is
// not emptied at start: others' uploads wait there), any replica's free worker
// runs a job, a dead replica's jobs run again elsewhere, and job() / jobs()
// read every replica's jobs from the database.
#include <condition_variable>
#include <filesystem>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "core/common/bounded_queue.h"
#include "core/common/ids.h"
#include "core/persistence/atlas_store.h"
#include "core/server/atlas_service.h"
#include "core/server/shared_job_queue.h"
#include "core/server/metrics_registry.h"

namespace orbatlas {

struct UploadJobOptions {
  std::filesystem::path work_dir;  // uploads and their extracted folders (cleaned up per job)
  std::size_t workers = 1;
  std::size_t max_queued = 8;

  // Throws Error naming the first value out of range.
  void check() const;
};

class UploadJobs {
 public:
  // `service` must outlive the jobs. Creates `work_dir` (emptied when it
  // exists), reads the stored jobs and marks the interrupted ones failed.
  UploadJobs(AtlasService& service, UploadJobOptions options);
  ~UploadJobs();  // stop()
  UploadJobs(const UploadJobs&) = delete;
  UploadJobs& operator=(const UploadJobs&) = delete;

  // A new, empty folder for an incoming upload (the HTTP layer extracts into it).
  std::filesystem::path new_upload_folder();
  // Whether the extracted upload in `folder` is a recording whose lists name
  // files inside it only (core/io/recording_paths.h): DataError naming the
  // list's line if not. The job reads it again (and checks the same).
  static void check_recording(const std::filesystem::path& folder);
  // Queues the extracted upload (the folder is now the job's; it is deleted when
  // the job ends). ServiceError 503 when the queue is full (the folder is deleted).
  JobId submit(const std::filesystem::path& folder, SessionRequest request, std::uint64_t archive_bytes);
  StoredJob job(JobId id) const;        // ServiceError 404
  std::vector<StoredJob> jobs() const;  // by id
  // Jobs not started are dropped; running ones end at their next frame. Idempotent.
  void stop();
  std::size_t count(const std::string& state) const;
  std::vector<prometheus::MetricFamily> metrics() const;  // orbatlas_jobs{state=...}

 private:
  struct Job {
    StoredJob row;  // what is stored and reported
    SessionRequest request;
    std::filesystem::path folder;  // the extracted upload
  };
  void work();
  void run(JobId id);
  // Changes a job under the mutex; `store`: then writes its row (outside the mutex).
  void update(JobId id, const std::function<void(Job&)>& change, bool store = true);
  void store_row(const StoredJob& row);

  // A shared atlas: the queue every replica's workers take from (null on SQLite).
  void work_shared();
  // Runs a job with its failure recorded (the worker's body).
  void run_recorded(JobId id);

  AtlasService& service_;
  const UploadJobOptions options_;
  std::unique_ptr<SharedJobQueue> shared_;
  std::condition_variable wake_;    // with mutex_: a job was submitted here, or stop()
  std::size_t submitted_ = 0;       // guarded by mutex_: jobs submitted here not yet looked for
  mutable std::mutex store_mutex_;  // guards store_ (a connection of its own)
  mutable std::optional<AtlasStore> store_;
  mutable std::mutex mutex_;  // guards jobs_, next_job_, next_upload_
  std::map<JobId, Job> jobs_;
  JobId next_job_ = 1;
  std::uint64_t next_upload_ = 0;
  std::atomic<bool> stopping_{false};
  mutable MetricsRegistry metrics_;
  BoundedQueue<JobId> queue_;
  std::vector<std::thread> workers_;  // last: started once everything above exists
};

}  // namespace orbatlas
