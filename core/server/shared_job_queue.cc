#include "core/server/shared_job_queue.h"

#include <nlohmann/json.hpp>

#include "core/common/error.h"
#include "core/persistence/pg_db.h"
#include "core/persistence/wall_clock.h"
#include "core/server/pg_connection.h"

namespace orbatlas {

std::string session_request_json(const SessionRequest& request) {
  nlohmann::json j = {{"name", request.name},
                      {"sensor", request.sensor},
                      {"mode", request.mode},
                      {"config", request.settings.config},
                      {"settings_yaml", request.settings.settings_yaml}};
  if (request.max_lag_s) j["max_lag_s"] = *request.max_lag_s;
  return j.dump();
}

SessionRequest session_request_from_json(const std::string& text) {
  try {
    const nlohmann::json j = nlohmann::json::parse(text);
    SessionRequest r;
    r.name = j.at("name").get<std::string>();
    r.sensor = j.at("sensor").get<std::string>();
    r.mode = j.at("mode").get<std::string>();
    r.settings.config = j.at("config").get<std::string>();
    r.settings.settings_yaml = j.at("settings_yaml").get<std::string>();
    if (j.contains("max_lag_s")) r.max_lag_s = j.at("max_lag_s").get<double>();
    return r;
  } catch (const nlohmann::json::exception& e) {
    throw DataError(std::string("a stored upload job's request is not readable: ") + e.what());
  }
}

SharedJobQueue::SharedJobQueue(const ReplicaRegistry& registry, std::string location)
    : registry_(registry), location_(std::move(location)) {
  ORBATLAS_CHECK(registry_.shared(), "the shared job queue is for a shared (PostgreSQL) atlas");
}

SharedJobQueue::~SharedJobQueue() = default;

void SharedJobQueue::add(JobId id, const std::filesystem::path& folder, const SessionRequest& request) {
  std::lock_guard lock(db_mutex_);
  on_pg_connection(db_, location_, [&](PgDb& db) {
    db.prepare("INSERT INTO shared_jobs(job_id, replica_id, folder, request) VALUES (?1, NULL, ?2, ?3)")
        .bind_int64(1, static_cast<std::int64_t>(id))
        .bind_text(2, folder.string())
        .bind_text(3, session_request_json(request))
        .run();
  });
}

std::optional<ClaimedJob> SharedJobQueue::claim() {
  if (registry_.lease_lost()) return std::nullopt;
  std::lock_guard lock(db_mutex_);
  return on_pg_connection(db_, location_, [&](PgDb& db) -> std::optional<ClaimedJob> {
    PgStatement take = db.prepare(
        "UPDATE shared_jobs SET replica_id = ?1, claimed_ns = ?2 WHERE job_id = ("
        "SELECT s.job_id FROM shared_jobs s JOIN upload_jobs u ON u.id = s.job_id "
        "WHERE s.replica_id IS NULL AND u.state = 'queued' ORDER BY s.job_id LIMIT 1 FOR UPDATE OF s SKIP LOCKED) "
        "RETURNING job_id, folder, request");
    take.bind_int64(1, static_cast<std::int64_t>(registry_.id())).bind_int64(2, unix_time_ns());
    if (!take.step()) return std::nullopt;
    ClaimedJob job;
    job.id = static_cast<JobId>(take.int64(0));
    job.folder = take.text(1);
    job.request = session_request_from_json(take.text(2));
    return job;
  });
}

void SharedJobQueue::remove(JobId id) {
  std::lock_guard lock(db_mutex_);
  on_pg_connection(db_, location_, [&](PgDb& db) {
    db.prepare("DELETE FROM shared_jobs WHERE job_id = ?1").bind_int64(1, static_cast<std::int64_t>(id)).run();
  });
}

std::size_t SharedJobQueue::requeue_dead() {
  std::lock_guard lock(db_mutex_);
  return on_pg_connection(db_, location_, [&](PgDb& db) {
    SqlTransaction transaction(db);
    const char* dead = "(SELECT id FROM replicas WHERE state <> 'running' OR lease_until < now())";
    // Uploads a dead replica was still receiving (its job ids are its own range's).
    db.exec(std::string("UPDATE upload_jobs SET state = 'failed', error = 'interrupted: the replica receiving "
                        "this upload stopped or died before it had all of it' WHERE state = 'extracting' AND "
                        "(id >> " +
                        std::to_string(kReplicaMapIdShift) + ") IN ") +
            dead);
    PgStatement again =
        db.prepare(std::string("UPDATE shared_jobs SET replica_id = NULL, claimed_ns = NULL WHERE replica_id IN ") +
                   dead + " RETURNING job_id");
    std::size_t n = 0;
    PgStatement queued = db.prepare(
        "UPDATE upload_jobs SET state = 'queued', frames_done = 0, tracked = 0, rejected = 0, error = "
        "'its replica stopped or died while it ran: started again' WHERE id = ?1 AND state IN ('queued', 'running')");
    std::vector<std::int64_t> ids;
    while (again.step()) ids.push_back(again.int64(0));
    for (const std::int64_t id : ids) {
      queued.bind_int64(1, id).run();
      queued.reset();
      ++n;
    }
    transaction.commit();
    return n;
  });
}

std::size_t SharedJobQueue::waiting() {
  std::lock_guard lock(db_mutex_);
  return on_pg_connection(db_, location_, [&](PgDb& db) {
    return static_cast<std::size_t>(db.query_int64("SELECT count(*) FROM shared_jobs WHERE replica_id IS NULL"));
  });
}

}  // namespace orbatlas
