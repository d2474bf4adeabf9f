#pragma once
// Uploaded recordings processed in the background (POST /v1/uploads): each job
// extracts a tar of an EuRoC ASL folder into the server's work folder, feeds its
// stereo frames to a new session of the service (as a live client would), finishes
// (stores) the session, and evaluates it when the recording has ground truth.
// `workers` threads take jobs from a bounded queue; a full queue refuses uploads
// (503) instead of piling them on disk.
#include <filesystem>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "core/common/bounded_queue.h"
#include "core/server/atlas_service.h"

namespace orbatlas {

using JobId = std::uint64_t;

struct UploadJobOptions {
  std::filesystem::path work_dir;  // uploads and their extracted folders (cleaned up per job)
  std::size_t workers = 1;
  std::size_t max_queued = 8;
};

class UploadJobs {
 public:
  // `service` must outlive the jobs. Creates `work_dir`.
  UploadJobs(AtlasService& service, UploadJobOptions options);
  ~UploadJobs();  // stop()
  UploadJobs(const UploadJobs&) = delete;
  UploadJobs& operator=(const UploadJobs&) = delete;

  // A fresh path for an incoming archive (the HTTP layer streams into it).
  std::filesystem::path new_upload_path();
  // Queues the archive (now owned by the job). ApiError 503 when the queue is full.
  JobId submit(const std::filesystem::path& archive, SessionRequest request);
  nlohmann::json job_json(JobId id) const;  // ApiError 404
  nlohmann::json jobs_json() const;
  // Jobs not started are dropped; running ones end at their next frame. Idempotent.
  void stop();
  std::size_t count(const std::string& state) const;  // metrics

 private:
  struct Job {
    JobId id = 0;
    SessionRequest request;
    std::filesystem::path archive;
    std::string state = "queued";  // queued, extracting, running, done, failed, cancelled
    std::size_t frames_total = 0, frames_done = 0, tracked = 0, rejected = 0;
    std::uint64_t archive_bytes = 0;
    std::optional<SessionId> session;
    std::optional<double> ate_rmse_m;
    std::string error;
  };
  void work();
  void run(JobId id);
  void update(JobId id, const std::function<void(Job&)>& change);
  static nlohmann::json to_json(const Job& job);

  AtlasService& service_;
  const UploadJobOptions options_;
  mutable std::mutex mutex_;  // guards jobs_, next_job_, next_upload_
  std::map<JobId, Job> jobs_;
  JobId next_job_ = 1;
  std::uint64_t next_upload_ = 0;
  std::atomic<bool> stopping_{false};
  BoundedQueue<JobId> queue_;
  std::vector<std::thread> workers_;  // last: started once everything above exists
};

}  // namespace orbatlas
