#include "core/server/map_leases.h"

#include "core/common/log.h"

namespace orbatlas {

void MapLeases::add_free(MapId map) {
  std::lock_guard lock(mutex_);
  if (!leases_.contains(map)) free_.insert(map);
}

bool MapLeases::claim(SessionId session, MapId map) {
  std::lock_guard lock(mutex_);
  if (const auto it = leases_.find(map); it != leases_.end()) return it->second.session == session;
  if (free_.erase(map) == 0) return false;  // another live session's new map
  leases_[map] = {session, true};
  return true;
}

bool MapLeases::is_free(MapId map) const {
  std::lock_guard lock(mutex_);
  return free_.contains(map);
}

bool MapLeases::hold(SessionId session, MapId map) {
  std::lock_guard lock(mutex_);
  if (const auto it = leases_.find(map); it != leases_.end()) {
    if (it->second.session != session) return false;
    it->second.tentative = false;
    return true;
  }
  if (free_.erase(map) == 0) return false;
  leases_[map] = {session, false};
  return true;
}

void MapLeases::settle(SessionId session, std::optional<MapId> tracked_in) {
  std::lock_guard lock(mutex_);
  if (tracked_in) {
    const auto it = leases_.find(*tracked_in);
    if (it == leases_.end()) {
      free_.erase(*tracked_in);  // a map the session created
      leases_[*tracked_in] = {session, false};
    } else if (it->second.session == session) {
      it->second.tentative = false;
    } else {
      log_warn("map " + std::to_string(*tracked_in) + " is held by session " + std::to_string(it->second.session) +
               " but session " + std::to_string(session) + " tracked in it");
    }
  }
  for (auto it = leases_.begin(); it != leases_.end();) {
    if (it->second.session == session && it->second.tentative) {
      free_.insert(it->first);
      it = leases_.erase(it);
    } else {
      ++it;
    }
  }
}

void MapLeases::release_all(SessionId session) {
  std::lock_guard lock(mutex_);
  for (auto it = leases_.begin(); it != leases_.end();) {
    if (it->second.session == session) {
      free_.insert(it->first);
      it = leases_.erase(it);
    } else {
      ++it;
    }
  }
}

void MapLeases::forget(MapId map) {
  std::lock_guard lock(mutex_);
  free_.erase(map);
  leases_.erase(map);
}

std::optional<SessionId> MapLeases::holder(MapId map) const {
  std::lock_guard lock(mutex_);
  const auto it = leases_.find(map);
  if (it == leases_.end()) return std::nullopt;
  return it->second.session;
}

std::vector<MapId> MapLeases::held_by(SessionId session) const {
  std::lock_guard lock(mutex_);
  std::vector<MapId> out;
  for (const auto& [map, lease] : leases_)
    if (lease.session == session) out.push_back(map);
  return out;
}

}  // namespace orbatlas
