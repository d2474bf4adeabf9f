#include "core/server/session_registry.h"

#include <algorithm>
#include <string>

#include "core/common/error.h"
#include "core/common/log.h"
#include "core/server/service_error.h"

namespace orbatlas {

SessionRegistry::SessionRegistry(std::size_t max_live_sessions) : max_live_sessions_(max_live_sessions) {
  ORBATLAS_CHECK(max_live_sessions_ > 0, "server: max_live_sessions must be > 0");
}

SessionRegistry::~SessionRegistry() { stop(); }

SessionId SessionRegistry::reserve_id() {
  std::lock_guard lock(mutex_);
  if (stopped_) throw ServiceError(ServiceErrorKind::kUnavailable, "shutting_down", "the server is shutting down");
  std::size_t live = 0;
  for (const auto& [_, s] : sessions_) live += s->state() == SessionState::kActive ? 1 : 0;
  if (live >= max_live_sessions_)
    throw ServiceError(ServiceErrorKind::kUnavailable, "too_many_sessions",
                       std::to_string(live) + " sessions are live; the limit is " + std::to_string(max_live_sessions_) +
                           " (finish one first)");
  return next_id_++;
}

void SessionRegistry::start_ids_at(SessionId first) {
  std::lock_guard lock(mutex_);
  next_id_ = std::max(next_id_, first);
}

void SessionRegistry::add_live(SessionId id, std::shared_ptr<LiveSession> session, SessionStart start) {
  {
    std::lock_guard lock(mutex_);
    sessions_[id] = std::move(session);
    starts_[id] = std::move(start);
  }
  wake_.notify_all();
}

bool SessionRegistry::add_stored(std::shared_ptr<LiveSession> session, bool own_id) {
  const SessionId id = session->id();
  std::lock_guard lock(mutex_);
  if (!sessions_.try_emplace(id, std::move(session)).second) return false;
  if (own_id) next_id_ = std::max(next_id_, id + 1);
  return true;
}

bool SessionRegistry::contains(SessionId id) const {
  std::lock_guard lock(mutex_);
  return sessions_.count(id) > 0;
}

std::shared_ptr<LiveSession> SessionRegistry::get(SessionId id) const {
  std::lock_guard lock(mutex_);
  const auto it = sessions_.find(id);
  if (it == sessions_.end()) throw_not_found("no session " + std::to_string(id));
  return it->second;
}

std::vector<std::shared_ptr<LiveSession>> SessionRegistry::all() const {
  std::lock_guard lock(mutex_);
  std::vector<std::shared_ptr<LiveSession>> out;
  for (const auto& [_, s] : sessions_) out.push_back(s);
  return out;
}

std::vector<std::shared_ptr<LiveSession>> SessionRegistry::active() const {
  std::lock_guard lock(mutex_);
  std::vector<std::shared_ptr<LiveSession>> out;
  for (const auto& [_, s] : sessions_)
    if (s->state() == SessionState::kActive) out.push_back(s);
  return out;
}

std::optional<SessionStart> SessionRegistry::start_of(SessionId id) const {
  std::lock_guard lock(mutex_);
  const auto it = starts_.find(id);
  if (it == starts_.end()) return std::nullopt;
  return it->second;
}

MapRig SessionRegistry::mapping_rig(SessionId id) const {
  std::lock_guard lock(mutex_);
  const auto it = starts_.find(id);
  if (it != starts_.end()) return it->second.rig;
  const auto s = sessions_.find(id);  // a stored session (this run did not start it)
  if (s == sessions_.end()) return {};
  const SensorType sensor = s->second->info().sensor;
  return MapRig{s->second->info().cameras, sensor == SensorType::kStereoInertial, is_single_camera(sensor)};
}

std::vector<SessionId> SessionRegistry::in_map(MapId map) const {
  std::vector<SessionId> in;
  std::lock_guard lock(mutex_);
  for (const auto& [id, s] : sessions_)
    if (s->current_map() == map) in.push_back(id);
  return in;
}

SessionRegistry::Counts SessionRegistry::counts() const {
  Counts out;
  std::lock_guard lock(mutex_);
  for (const auto& [_, s] : sessions_) {
    const bool live = s->state() == SessionState::kActive;
    out.live += live ? 1 : 0;
    out.ended += live ? 0 : 1;
    out.worker_errors += s->worker_errors();
  }
  return out;
}

std::size_t SessionRegistry::size() const {
  std::lock_guard lock(mutex_);
  return sessions_.size();
}

void SessionRegistry::expire_idle_sessions(double timeout_s, std::function<void(SessionId)> finish) {
  ORBATLAS_CHECK(timeout_s > 0.0 && finish, "idle expiry needs a timeout > 0 and a finish");
  const auto timeout = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double>(std::min(timeout_s, 3.15e7)));
  std::lock_guard lock(mutex_);
  ORBATLAS_CHECK(!idle_thread_.joinable(), "idle expiry runs already");
  if (stopped_) return;
  idle_thread_ = std::thread([this, timeout, finish = std::move(finish)] { expire_until_stopped(timeout, finish); });
}

void SessionRegistry::expire_until_stopped(std::chrono::steady_clock::duration timeout,
                                           const std::function<void(SessionId)>& finish) {
  std::unique_lock lock(mutex_);
  while (!stopped_) {
    const auto now = std::chrono::steady_clock::now();
    std::vector<std::shared_ptr<LiveSession>> idle;
    auto next = std::chrono::steady_clock::time_point::max();
    for (const auto& [id, s] : sessions_) {
      if (s->state() != SessionState::kActive) continue;
      const auto deadline = s->last_activity() + timeout;
      if (deadline <= now) {
        idle.push_back(s);
      } else {
        next = std::min(next, deadline);
      }
    }
    if (idle.empty()) {
      // Until the earliest deadline (a new session's is later than all of them).
      if (next == std::chrono::steady_clock::time_point::max()) {
        wake_.wait(lock);
      } else {
        wake_.wait_until(lock, next);
      }
      continue;
    }
    lock.unlock();
    for (const auto& s : idle) {
      // Activity may have come meanwhile: only a session still idle is ended.
      if (std::chrono::steady_clock::now() - s->last_activity() < timeout) continue;
      try {
        finish(s->id());
      } catch (const std::exception& e) {
        log_warn("session " + std::to_string(s->id()) + ": finishing it after its idle timeout failed: " + e.what());
      }
    }
    lock.lock();
  }
}

bool SessionRegistry::stop() {
  {
    std::lock_guard lock(mutex_);
    if (stopped_) return false;
    stopped_ = true;
  }
  wake_.notify_all();
  if (idle_thread_.joinable()) idle_thread_.join();  // it may be finishing a session: let it end
  return true;
}

bool SessionRegistry::stopped() const {
  std::lock_guard lock(mutex_);
  return stopped_;
}

}  // namespace orbatlas
