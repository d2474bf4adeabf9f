#include "core/server/upload_jobs.h"

#include <chrono>
#include <set>
#include <opencv2/imgcodecs.hpp>

#include "core/common/log.h"
#include "core/common/thread_name.h"
#include "core/eval/evaluate.h"
#include "core/io/euroc_reader.h"
#include "core/io/imu_batches.h"
#include "core/io/tum_rgbd.h"
#include "core/io/tum_trajectory.h"
#include "core/io/kitti_odometry.h"
#include "core/server/service_error.h"
#include "core/server/uploaded_recording.h"

namespace orbatlas {
namespace {

namespace fs = std::filesystem;

struct RemoveOnExit {
  fs::path path;
  ~RemoveOnExit() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

// What an interrupted job's session holds: the frames its last checkpoint stored.
std::string kept_of_session(AtlasStore& store, SessionId session) {
  const std::size_t kept = store.load_trajectory(session).size();
  if (kept == 0) return "; nothing of it was stored (session " + std::to_string(session) + " holds no frame)";
  return "; session " + std::to_string(session) + " keeps the " + std::to_string(kept) +
         " tracked frames its last checkpoint stored";
}

}  // namespace

void UploadJobOptions::check() const {
  ORBATLAS_CHECK(!work_dir.empty(), "uploads need a work folder");
  ORBATLAS_CHECK(workers > 0, "uploads: workers must be > 0, not " << workers);
  ORBATLAS_CHECK(max_queued > 0, "uploads: max_queued must be > 0, not " << max_queued);
}

UploadJobs::UploadJobs(AtlasService& service, UploadJobOptions options)
    : service_(service), options_((options.check(), std::move(options))), queue_(options_.max_queued) {
  // What an earlier run left (a killed upload, an extraction cut short) is
  // nobody's any more: no job reads what it did not write itself.
  std::error_code ec;
  std::size_t leftovers = 0;
  if (service_.replica().shared())
    shared_ = std::make_unique<SharedJobQueue>(service_.replica(), service_.db_path().string());
  // A shared work folder holds other replicas' uploads: not emptied.
  if (!shared_ && fs::is_directory(options_.work_dir, ec)) {
    for (const auto& entry : fs::directory_iterator(options_.work_dir)) {
      fs::remove_all(entry.path(), ec);
      ++leftovers;
    }
  }
  if (leftovers > 0)
    log_warn("uploads: removed " + std::to_string(leftovers) + " leftovers of an earlier run from " +
             options_.work_dir.string());
  fs::create_directories(options_.work_dir);
  store_.emplace(AtlasStore::open(service_.db_path(), service_.vocabulary().hash()));
  // Replicas of a shared atlas: job ids from this replica's range; the jobs of
  // live replicas are theirs (only a dead replica's are interrupted).
  const ReplicaRegistry& replica = service_.replica();
  std::set<std::uint64_t> others_alive;
  if (replica.shared()) {
    for (const ReplicaInfo& r : replica.replicas())
      if (r.alive && !r.self) others_alive.insert(r.id);
    next_job_ = replica_id_range(replica.id(), kReplicaMapIdShift).begin;
  }
  // A shared queue: a dead replica's jobs wait again (those it was receiving fail) first.
  if (shared_) shared_->requeue_dead();
  for (StoredJob& row : store_->load_jobs()) {
    const bool others = others_alive.count(replica_of_id(row.id, kReplicaMapIdShift)) > 0;
    // (A queued job of a shared queue waits for any replica's worker.)
    const bool waiting = shared_ && row.state == "queued";
    if (!others && !waiting && (row.state == "queued" || row.state == "extracting" || row.state == "running")) {
      row.error =
          "interrupted: the server stopped without finishing this job (it was killed or crashed) while it was " +
          row.state + (row.session ? kept_of_session(*store_, *row.session) : std::string());
      row.state = "failed";
      store_->save_job(row);
    }
    if (!replica.shared() || replica_id_range(replica.id(), kReplicaMapIdShift).contains(row.id))
      next_job_ = std::max(next_job_, row.id + 1);
    Job job;
    job.request.name = row.name;
    job.row = std::move(row);
    jobs_[job.row.id] = std::move(job);
  }
  for (std::size_t i = 0; i < std::max<std::size_t>(1, options_.workers); ++i)
    workers_.emplace_back([this] {
      set_current_thread_name("uploads");
      shared_ ? work_shared() : work();
    });
}

UploadJobs::~UploadJobs() { stop(); }

void UploadJobs::stop() {
  stopping_ = true;
  queue_.close();
  {
    std::lock_guard lock(mutex_);  // no worker between its test of stopping_ and its wait
  }
  wake_.notify_all();
  for (auto& w : workers_)
    if (w.joinable()) w.join();
  std::vector<StoredJob> cancelled;
  std::vector<fs::path> folders;
  {
    std::lock_guard lock(mutex_);
    for (auto& [_, job] : jobs_) {
      if (job.row.state == "queued" && !shared_) {  // a shared queue's jobs wait for another replica
        job.row.state = "cancelled";
        job.row.error = "the server stopped before this job started";
        folders.push_back(job.folder);
        cancelled.push_back(job.row);
      }
    }
  }
  // Files are removed outside the (leaf) lock.
  for (const fs::path& folder : folders) {
    std::error_code ec;
    fs::remove_all(folder, ec);
  }
  for (const StoredJob& row : cancelled) store_row(row);
}

void UploadJobs::store_row(const StoredJob& row) {
  try {
    std::lock_guard lock(store_mutex_);
    store_->save_job(row);
  } catch (const std::exception& e) {
    log_warn("upload job " + std::to_string(row.id) + ": cannot store its state: " + e.what());
  }
}

fs::path UploadJobs::new_upload_folder() {
  fs::path folder;
  {
    std::lock_guard lock(mutex_);
    // Replicas share the folder: each names its uploads apart.
    folder = options_.work_dir / ((shared_ ? "upload-r" + std::to_string(service_.replica().id()) + "-" : "upload-") +
                                  std::to_string(next_upload_++));
  }
  // New: an upload reads nothing it did not extract itself.
  ORBATLAS_CHECK(fs::create_directory(folder), "the upload folder " << folder.filename().string() << " exists already");
  return folder;
}

void UploadJobs::check_recording(const fs::path& folder) { check_uploaded_recording(folder); }

JobId UploadJobs::submit(const fs::path& folder, SessionRequest request, std::uint64_t archive_bytes) {
  Job job;
  job.request = std::move(request);
  job.folder = folder;
  job.row.name = job.request.name;
  job.row.state = "queued";
  job.row.created_ns =
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
  job.row.archive_bytes = archive_bytes;
  {
    std::lock_guard lock(mutex_);
    job.row.id = next_job_++;
    jobs_[job.row.id] = job;
  }
  const JobId id = job.row.id;
  if (shared_) {
    // The shared queue's jobs are the database's: whichever replica claims one
    // keeps it in its jobs_ while it runs it (job() and jobs() read the database).
    {
      std::lock_guard lock(mutex_);
      jobs_.erase(id);
    }
    std::size_t waiting = 0;
    bool full = false;
    try {
      waiting = shared_->waiting();
      full = waiting >= options_.max_queued;
      if (!full) {
        store_row(job.row);
        shared_->add(id, folder, job.request);
      }
    } catch (const std::exception& e) {
      std::error_code ec;
      fs::remove_all(folder, ec);
      throw ServiceError(ServiceErrorKind::kUnavailable, "busy",
                         std::string("cannot queue the upload in the shared queue: ") + e.what());
    }
    if (full) {
      std::error_code ec;
      fs::remove_all(folder, ec);
      throw ServiceError(ServiceErrorKind::kUnavailable, "busy",
                         "the shared upload queue is full (" + std::to_string(waiting) + " jobs waiting); retry later");
    }
    {
      std::lock_guard lock(mutex_);
      ++submitted_;
    }
    wake_.notify_one();
    return id;
  }
  if (!queue_.try_push(id)) {
    {
      std::lock_guard lock(mutex_);
      jobs_.erase(id);
    }
    std::error_code ec;
    fs::remove_all(folder, ec);
    throw ServiceError(ServiceErrorKind::kUnavailable, "busy",
                       "the upload queue is full (" + std::to_string(options_.max_queued) + " jobs); retry later");
  }
  store_row(job.row);  // the id is taken for good (the worker's first update comes after)
  return id;
}

void UploadJobs::update(JobId id, const std::function<void(Job&)>& change, bool store) {
  StoredJob row;
  {
    std::lock_guard lock(mutex_);
    Job& job = jobs_.at(id);
    change(job);
    row = job.row;
  }
  if (store) store_row(row);
}

void UploadJobs::work() {
  while (auto id = queue_.pop()) run_recorded(*id);
}

void UploadJobs::work_shared() {
  const auto period = std::chrono::duration<double>(service_.replica().options().lease_s);
  while (!stopping_) {
    std::optional<ClaimedJob> claimed;
    try {
      shared_->requeue_dead();
      claimed = shared_->claim();
    } catch (const std::exception& e) {
      log_warn(std::string("uploads: the shared queue cannot be read (tried again later): ") + e.what());
    }
    if (!claimed) {
      // Woken by a job submitted here; others' are looked for once per lease.
      std::unique_lock lock(mutex_);
      wake_.wait_for(lock, period, [this] { return stopping_ || submitted_ > 0; });
      if (submitted_ > 0) --submitted_;
      continue;
    }
    {
      std::optional<StoredJob> row;
      {
        std::lock_guard lock(store_mutex_);
        row = store_->load_job(claimed->id);
      }
      std::lock_guard lock(mutex_);
      Job& job = jobs_[claimed->id];
      if (row) job.row = std::move(*row);
      job.row.id = claimed->id;
      job.request = claimed->request;
      job.folder = claimed->folder;
    }
    log_info("upload job " + std::to_string(claimed->id) + " taken from the shared queue by replica " +
             std::to_string(service_.replica().id()));
    run_recorded(claimed->id);
    try {
      shared_->remove(claimed->id);
    } catch (const std::exception& e) {
      log_warn("upload job " + std::to_string(claimed->id) + ": cannot leave the shared queue: " + e.what());
    }
  }
}

void UploadJobs::run_recorded(JobId id) {
  fs::path folder;
  {
    std::lock_guard lock(mutex_);
    folder = jobs_.at(id).folder;
  }
  try {
    run(id);
  } catch (const std::exception& e) {
    log_warn("upload job " + std::to_string(id) + " failed: " + e.what());
    // Paths inside the archive, not the server's folders.
    std::string message = e.what();
    for (const std::string& prefix : {folder.string() + "/", options_.work_dir.string()})
      for (std::size_t at; (at = message.find(prefix)) != std::string::npos;)
        message.replace(at, prefix.size(), prefix.back() == '/' ? "" : "<work>");
    update(id, [&](Job& j) {
      j.row.state = "failed";
      j.row.error = message;
    });
  }
}

void UploadJobs::run(JobId id) {
  fs::path folder;
  SessionRequest request;
  update(id, [&](Job& j) {
    j.row.state = "running";
    folder = j.folder;
    request = j.request;
  });
  const RemoveOnExit remove_folder{folder};
  const fs::path root = uploaded_recording_root(folder);
  // An upload without settings takes the recording's own: a KITTI sequence's
  // from its calib.txt, else euroc/stereo.
  if (request.settings.config.empty() && request.settings.settings_yaml.empty()) {
    if (is_kitti_sequence(root))
      request.settings.settings_yaml = kitti_settings_yaml(read_kitti_sequence(root, /*confined=*/true));
    else
      request.settings.config = "euroc/stereo";
  }
  const SensorType sensor = service_.request_sensor(request);
  const bool rgbd = sensor == SensorType::kRgbd;
  const UploadedRecording recording = read_uploaded_recording(root, sensor);
  const std::vector<DatasetFrame>& frames = recording.frames;
  if (request.name.empty()) request.name = "upload " + std::to_string(id);
  const SessionId session = service_.create_session(request);
  update(id, [&](Job& j) {
    j.row.name = request.name;
    j.row.session = session;
    j.row.frames_total = frames.size();
  });
  std::size_t tracked = 0, rejected = 0, imu_next = 0;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    if (stopping_) break;  // the service's shutdown finishes and stores the session
    if (!recording.imu.empty()) {
      // As a device sends it (a session without an inertial config only counts it).
      try {
        service_.add_imu(session, take_imu_batch(recording.imu, imu_next, frames[i].t_ns));
      } catch (const DataError& e) {
        log_warn("upload job " + std::to_string(id) + ": IMU skipped: " + e.what());
      }
    }
    const cv::Mat left = cv::imread(frames[i].left.string(), cv::IMREAD_GRAYSCALE);
    // An RGB-D frame's second image is its 16-bit depth image, read as it is.
    const bool single = frames[i].right.empty();  // a single camera's frame
    const cv::Mat right =
        single ? cv::Mat() : cv::imread(frames[i].right.string(), rgbd ? cv::IMREAD_UNCHANGED : cv::IMREAD_GRAYSCALE);
    try {
      ORBATLAS_DATA_CHECK(!left.empty() && (single || !right.empty()), "cannot read the images at " << frames[i].t_ns);
      if (service_.process_frame(session, frames[i].t_ns, left, right).result.tracked) ++tracked;
    } catch (const DataError& e) {
      ++rejected;
      log_warn("upload job " + std::to_string(id) + ": frame skipped: " + e.what());
    }
    update(
        id,
        [&](Job& j) {
          j.row.frames_done = i + 1;
          j.row.tracked = tracked;
          j.row.rejected = rejected;
        },
        (i + 1) % 200 == 0);  // the progress is stored now and then, the states always
  }
  service_.finish_session(session);
  std::optional<double> ate;
  if (!recording.ground_truth.empty()) {
    const Trajectory trajectory = service_.trajectory(session).poses;
    try {
      EvalOptions eval;
      eval.estimate_T_b_x = recording.T_b_c0;
      // A single camera's map has its own scale, unless its IMU made it metric.
      if (recording.T_b_c0 && sensor != SensorType::kMonocularInertial) eval.align = AlignMode::kSim3;
      if (trajectory.size() >= 3)
        ate = evaluate_trajectory(trajectory, from_ground_truth_states(recording.ground_truth), eval).ate.rmse;
    } catch (const Error& e) {
      log_warn("upload job " + std::to_string(id) + ": no ATE: " + e.what());
    }
  }
  // The files go before the job is reported done (a client may look at once).
  std::error_code ec;
  fs::remove_all(folder, ec);
  update(id, [&](Job& j) {
    j.row.state = stopping_ ? "cancelled" : "done";
    if (stopping_) j.row.error = "the server stopped; the frames processed so far are stored";
    j.row.ate_rmse_m = ate;
  });
}

std::vector<prometheus::MetricFamily> UploadJobs::metrics() const {
  std::map<std::string, std::size_t> by_state;
  if (shared_) {  // one read of the database for every state
    try {
      for (const StoredJob& row : jobs()) ++by_state[row.state];
    } catch (const std::exception& e) {
      log_warn(std::string("uploads: cannot count the jobs: ") + e.what());
    }
  }
  for (const char* state : {"queued", "running", "done", "failed", "cancelled"})
    metrics_.gauge("orbatlas_jobs", "Upload jobs by state.", {{"state", state}})
        .Set(static_cast<double>(shared_ ? by_state[state] : count(state)));
  return metrics_.collect();
}

StoredJob UploadJobs::job(JobId id) const {
  if (shared_) {  // any replica's, as the database has it
    std::optional<StoredJob> row;
    {
      std::lock_guard lock(store_mutex_);
      row = store_->load_job(id);
    }
    if (!row) throw_not_found("no job " + std::to_string(id));
    return std::move(*row);
  }
  std::lock_guard lock(mutex_);
  const auto it = jobs_.find(id);
  if (it == jobs_.end()) throw_not_found("no job " + std::to_string(id));
  return it->second.row;
}

std::vector<StoredJob> UploadJobs::jobs() const {
  if (shared_) {  // every replica's, as the database has them
    std::lock_guard lock(store_mutex_);
    return store_->load_jobs();
  }
  std::lock_guard lock(mutex_);
  std::vector<StoredJob> list;
  for (const auto& [_, job] : jobs_) list.push_back(job.row);
  return list;
}

std::size_t UploadJobs::count(const std::string& state) const {
  if (shared_) {  // every replica's (a job this one queued may run on another)
    std::size_t n = 0;
    try {
      for (const StoredJob& row : jobs()) n += row.state == state ? 1 : 0;
    } catch (const std::exception& e) {
      log_warn(std::string("uploads: cannot count the jobs: ") + e.what());
    }
    return n;
  }
  std::lock_guard lock(mutex_);
  std::size_t n = 0;
  for (const auto& [_, job] : jobs_) n += job.row.state == state ? 1 : 0;
  return n;
}

}  // namespace orbatlas
