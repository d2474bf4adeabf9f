#include "core/server/replica_registry.h"

#include <unistd.h>

#include <chrono>
#include <climits>
#include <cmath>
#include <cstdio>

#include "core/common/error.h"
#include "core/common/log.h"
#include "core/persistence/atlas_location.h"
#include "core/persistence/pg_db.h"
#include "core/persistence/process_holder.h"
#include "core/persistence/wall_clock.h"

namespace orbatlas {
namespace {

std::string seconds_text(double s) {
  char text[32];
  std::snprintf(text, sizeof text, "%g s", s);
  return text;
}

// How long the rows of replicas that are gone stay listed.
constexpr double kForgetAfterS = 24 * 3600.0;

}  // namespace

void ReplicaOptions::check() const {
  ORBATLAS_CHECK(std::isfinite(lease_s) && lease_s >= 0.2 && lease_s <= 3600.0,
                 "replica: lease_s must be in 0.2..3600 s, not " << lease_s);
  ORBATLAS_CHECK(url.size() <= 2048, "replica: the url is longer than 2048 characters");
}

ReplicaRegistry::ReplicaRegistry(const std::filesystem::path& db, ReplicaOptions options)
    : options_((options.check(), std::move(options))),
      url_(options_.url),
      location_(db.string()),
      shared_(is_postgres_location(location_)),
      started_ns_(unix_time_ns()),
      holder_(process_holder()) {
  if (!shared_) return;
  renew_db_ = std::make_unique<PgDb>(location_);
  renew_db_->prepare("DELETE FROM replicas WHERE lease_until < now() - make_interval(secs => ?1)")
      .bind_real(1, kForgetAfterS)
      .run();
  PgStatement add = renew_db_->prepare(
      "INSERT INTO replicas(holder, url, started_ns, lease_until, state) "
      "VALUES (?1, ?2, ?3, now() + make_interval(secs => ?4), 'running') RETURNING id");
  add.bind_text(1, holder_).bind_text(2, options_.url).bind_int64(3, started_ns_).bind_real(4, options_.lease_s);
  ORBATLAS_CHECK(add.step(), "replicas: the new replica's row returned no id");
  id_ = static_cast<std::uint64_t>(add.int64(0));
  ORBATLAS_CHECK(id_ <= kMaxReplicaId, "replicas: the database has handed out replica id "
                                           << id_ << ", above the " << kMaxReplicaId
                                           << " whose id ranges fit in 63 bits (reset its `replicas` sequence)");
  log_info("replica " + std::to_string(id_) + " of the atlas " + location_for_messages(location_) + " (lease " +
           seconds_text(options_.lease_s) + ")");
  renewer_ = std::thread([this] { renew_until_stopped(); });
}

ReplicaRegistry::~ReplicaRegistry() { stop(); }

void ReplicaRegistry::renew_until_stopped() {
  const auto period = std::chrono::duration<double>(options_.lease_s / 3.0);
  std::unique_lock lock(stop_mutex_);
  while (!stop_cv_.wait_for(lock, period, [this] { return stopping_; })) {
    lock.unlock();
    renew_once();
    lock.lock();
    if (lease_lost_) return;
  }
}

void ReplicaRegistry::renew_once() {
  try {
    if (!renew_db_) renew_db_ = std::make_unique<PgDb>(location_);
    // Only a lease that has not passed is renewed.
    PgStatement renew = renew_db_->prepare(
        "UPDATE replicas SET lease_until = now() + make_interval(secs => ?2) "
        "WHERE id = ?1 AND state = 'running' AND lease_until >= now()");
    renew.bind_int64(1, static_cast<std::int64_t>(id_)).bind_real(2, options_.lease_s).run();
    if (renew.changes() == 1) {
      ++renewals_;
      return;
    }
    lease_lost_ = true;
    log_warn("replica " + std::to_string(id_) +
             ": its lease passed before it was renewed (the database unreachable, "
             "or this process stopped, for more than " +
             seconds_text(options_.lease_s) + "); other replicas may hold what it held");
  } catch (const std::exception& e) {
    ++failed_renewals_;
    renew_db_.reset();  // reconnect next time
    log_warn("replica " + std::to_string(id_) + ": cannot renew its lease: " + e.what());
  }
}

void ReplicaRegistry::set_url(const std::string& url) {
  ORBATLAS_CHECK(url.size() <= 2048, "replica: the url is longer than 2048 characters");
  if (shared_) {
    std::lock_guard lock(query_mutex_);
    try {
      if (!query_db_) query_db_ = std::make_unique<PgDb>(location_);
      query_db_->prepare("UPDATE replicas SET url = ?2 WHERE id = ?1")
          .bind_int64(1, static_cast<std::int64_t>(id_))
          .bind_text(2, url)
          .run();
    } catch (const std::exception&) {
      query_db_.reset();  // reconnect next time
      throw;
    }
  }
  std::lock_guard lock(url_mutex_);
  url_ = url;
}

std::string ReplicaRegistry::url() const {
  std::lock_guard lock(url_mutex_);
  return url_;
}

std::vector<ReplicaInfo> ReplicaRegistry::replicas() const {
  if (!shared_) {
    ReplicaInfo self;
    self.id = id_;
    self.holder = holder_;
    self.url = url();
    self.started_ns = started_ns_;
    self.state = stopped_ ? "stopped" : "running";
    self.alive = true;
    self.self = true;
    return {self};
  }
  std::lock_guard lock(query_mutex_);
  std::vector<ReplicaInfo> out;
  try {
    if (!query_db_) query_db_ = std::make_unique<PgDb>(location_);
    PgStatement rows = query_db_->prepare(
        "SELECT id, holder, url, started_ns, state, "
        "CAST(EXTRACT(EPOCH FROM lease_until - now()) AS double precision) FROM replicas ORDER BY id");
    while (rows.step()) {
      ReplicaInfo r;
      r.id = static_cast<std::uint64_t>(rows.int64(0));
      r.holder = rows.text(1);
      r.url = rows.text(2);
      r.started_ns = rows.int64(3);
      r.state = rows.text(4);
      r.lease_left_s = rows.real(5);
      r.alive = r.state == "running" && *r.lease_left_s >= 0.0;
      r.self = r.id == id_;
      out.push_back(std::move(r));
    }
  } catch (const std::exception&) {
    query_db_.reset();  // reconnect next time
    throw;
  }
  return out;
}

void ReplicaRegistry::stop() {
  {
    std::lock_guard lock(stop_mutex_);
    if (stopping_) return;
    stopping_ = true;
  }
  stop_cv_.notify_all();
  if (renewer_.joinable()) renewer_.join();
  if (shared_ && !lease_lost_) {
    try {
      if (!renew_db_) renew_db_ = std::make_unique<PgDb>(location_);
      renew_db_->prepare("UPDATE replicas SET state = 'stopped', lease_until = now() WHERE id = ?1")
          .bind_int64(1, static_cast<std::int64_t>(id_))
          .run();
    } catch (const std::exception& e) {
      log_warn("replica " + std::to_string(id_) +
               ": cannot record its stop (its lease will pass instead): " + e.what());
    }
  }
  stopped_ = true;
}

}  // namespace orbatlas
