#include "core/server/map_leases.h"

namespace orbatlas {

void MapLeases::add_free(MapId map) {
  std::lock_guard lock(mutex_);
  if (!leases_.contains(map)) free_.insert(map);
}

bool MapLeases::claim(SessionId session, MapId map) {
  std::lock_guard lock(mutex_);
  if (const auto it = leases_.find(map); it != leases_.end()) {
    if (it->second.contains(session)) return true;
    for (const auto& [holder, lease] : it->second)
      if (lease.exclusive) return false;
    it->second[session] = {.tentative = true};
    return true;
  }
  if (free_.erase(map) == 0) return false;  // unknown: a live session's map before its first settle
  leases_[map][session] = {.tentative = true};
  return true;
}

bool MapLeases::claim_exclusive(SessionId owner, MapId map) {
  std::lock_guard lock(mutex_);
  if (const auto it = leases_.find(map); it != leases_.end()) {
    if (it->second.size() != 1 || !it->second.contains(owner)) return false;
    it->second[owner] = {.tentative = false, .exclusive = true};
    return true;
  }
  if (free_.erase(map) == 0) return false;
  leases_[map][owner] = {.tentative = false, .exclusive = true};
  return true;
}

bool MapLeases::is_free(MapId map) const {
  std::lock_guard lock(mutex_);
  return free_.contains(map);
}

bool MapLeases::share(MapId source, MapId target) {
  std::lock_guard lock(mutex_);
  const auto it = leases_.find(target);
  if (it != leases_.end())
    for (const auto& [holder, lease] : it->second)
      if (lease.exclusive) return false;
  const auto from = leases_.find(source);
  if (from == leases_.end()) return true;  // nobody to move over
  free_.erase(target);
  auto& into = leases_[target];
  for (const auto& [holder, lease] : from->second) into[holder] = {.tentative = false};
  return true;
}

void MapLeases::settle(SessionId session, std::optional<MapId> tracked_in) {
  std::lock_guard lock(mutex_);
  if (tracked_in) {
    free_.erase(*tracked_in);  // a map the session created is known from now on
    leases_[*tracked_in][session].tentative = false;
  }
  std::vector<MapId> tentative;
  for (const auto& [map, holders] : leases_)
    if (const auto it = holders.find(session); it != holders.end() && it->second.tentative) tentative.push_back(map);
  for (const MapId map : tentative) give_back(map, session);
}

void MapLeases::give_back(MapId map, SessionId session) {
  const auto it = leases_.find(map);
  if (it == leases_.end()) return;
  it->second.erase(session);
  if (it->second.empty()) {
    leases_.erase(it);
    free_.insert(map);
  }
}

void MapLeases::release_all(SessionId session) {
  std::lock_guard lock(mutex_);
  std::vector<MapId> held;
  for (const auto& [map, holders] : leases_)
    if (holders.contains(session)) held.push_back(map);
  for (const MapId map : held) give_back(map, session);
}

void MapLeases::forget(MapId map) {
  std::lock_guard lock(mutex_);
  free_.erase(map);
  leases_.erase(map);
}

std::vector<SessionId> MapLeases::holders(MapId map) const {
  std::lock_guard lock(mutex_);
  std::vector<SessionId> out;
  if (const auto it = leases_.find(map); it != leases_.end())
    for (const auto& [holder, lease] : it->second) out.push_back(holder);
  return out;
}

std::vector<MapId> MapLeases::held_by(SessionId session) const {
  std::lock_guard lock(mutex_);
  std::vector<MapId> out;
  for (const auto& [map, holders] : leases_)
    if (holders.contains(session)) out.push_back(map);
  return out;
}

}  // namespace orbatlas
