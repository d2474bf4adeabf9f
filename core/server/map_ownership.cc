#include "core/server/map_ownership.h"

#include <algorithm>

#include "core/common/error.h"
#include "core/common/log.h"
#include "core/persistence/pg_db.h"
#include "core/persistence/wall_clock.h"
#include "core/server/pg_connection.h"

namespace orbatlas {

MapOwnership::MapOwnership(const ReplicaRegistry& registry, std::string location)
    : registry_(registry), location_(std::move(location)) {
  ORBATLAS_CHECK(registry_.shared(), "map ownership is for a shared (PostgreSQL) atlas");
}

MapOwnership::~MapOwnership() = default;

std::vector<MapId> MapOwnership::claim_free_and_dead() {
  if (registry_.lease_lost()) return {};
  std::lock_guard lock(db_mutex_);
  std::vector<MapId> claimed;
  on_pg_connection(db_, location_, [&](PgDb& db) {
    SqlTransaction transaction(db);
    const auto me = static_cast<std::int64_t>(registry_.id());
    const std::int64_t now = unix_time_ns();
    // Stored maps nobody owns.
    PgStatement free = db.prepare(
        "INSERT INTO map_owners(map_id, replica_id, claimed_ns) SELECT id, ?1, ?2 FROM maps "
        "WHERE id NOT IN (SELECT map_id FROM map_owners) ON CONFLICT (map_id) DO NOTHING RETURNING map_id");
    free.bind_int64(1, me).bind_int64(2, now);
    std::string why;  // for the log: how each map was claimed
    const auto note = [&](MapId map, const std::string& how) {
      why += (why.empty() ? "" : ", ") + std::to_string(map) + " (" + how + ")";
    };
    while (free.step()) {
      claimed.push_back(static_cast<MapId>(free.int64(0)));
      note(claimed.back(), "stored, no owner");
    }
    // The maps of dead replicas (waits for a checkpoint of theirs in progress).
    PgStatement dead = db.prepare(
        "UPDATE map_owners SET replica_id = ?1, claimed_ns = ?2 WHERE replica_id <> ?1 AND replica_id IN "
        "(SELECT id FROM replicas WHERE state <> 'running' OR lease_until < now()) RETURNING map_id");
    dead.bind_int64(1, me).bind_int64(2, now);
    while (dead.step()) {
      claimed.push_back(static_cast<MapId>(dead.int64(0)));
      note(claimed.back(), "its replica stopped or its lease passed");
    }
    // Maps handed over to this replica by live ones (hand_over()).
    PgStatement mine = db.prepare("SELECT map_id FROM map_owners WHERE replica_id = ?1");
    mine.bind_int64(1, me);
    while (mine.step()) {
      const auto map = static_cast<MapId>(mine.int64(0));
      if (!owns(map) && std::find(claimed.begin(), claimed.end(), map) == claimed.end()) {
        claimed.push_back(map);
        note(map, "its owner row names this replica");
      }
    }
    transaction.commit();
    if (!why.empty()) log_info("replica " + std::to_string(me) + " claims map(s) " + why);
  });
  return claimed;
}

void MapOwnership::ready(const std::vector<MapId>& maps) {
  std::lock_guard lock(mutex_);
  ready_.insert(maps.begin(), maps.end());
  for (const MapId map : maps) given_.erase(map);
}

bool MapOwnership::handed_over(MapId map) const {
  std::lock_guard lock(mutex_);
  return given_.count(map) > 0;
}

bool MapOwnership::owns(MapId map) const {
  if (registry_.lease_lost()) return false;
  std::lock_guard lock(mutex_);
  if (given_.count(map)) return false;
  return made_here(map) || ready_.count(map) > 0;
}

bool MapOwnership::want(MapId map) {
  if (registry_.lease_lost()) return false;
  std::lock_guard lock(db_mutex_);
  return on_pg_connection(db_, location_, [&](PgDb& db) {
    PgStatement ask = db.prepare(
        "UPDATE map_owners SET wanted_by = ?2 WHERE map_id = ?1 AND replica_id IS NOT NULL AND replica_id <> ?2");
    ask.bind_int64(1, static_cast<std::int64_t>(map)).bind_int64(2, static_cast<std::int64_t>(registry_.id()));
    ask.run();
    return ask.changes() > 0;
  });
}

std::vector<MapOwnership::Wanted> MapOwnership::wanted() const {
  std::lock_guard lock(db_mutex_);
  std::vector<Wanted> out;
  on_pg_connection(db_, location_, [&](PgDb& db) {
    PgStatement rows = db.prepare(
        "SELECT o.map_id, o.wanted_by FROM map_owners o JOIN replicas r ON r.id = o.wanted_by "
        "WHERE o.replica_id = ?1 AND r.state = 'running' AND r.lease_until >= now() ORDER BY o.map_id");
    rows.bind_int64(1, static_cast<std::int64_t>(registry_.id()));
    while (rows.step()) out.push_back({static_cast<MapId>(rows.int64(0)), static_cast<std::uint64_t>(rows.int64(1))});
  });
  return out;
}

bool MapOwnership::hand_over(MapId map, std::uint64_t to) {
  if (registry_.lease_lost()) return false;
  std::lock_guard lock(db_mutex_);
  const bool given = on_pg_connection(db_, location_, [&](PgDb& db) {
    PgStatement give = db.prepare(
        "UPDATE map_owners SET replica_id = ?3, wanted_by = NULL, claimed_ns = ?4 WHERE map_id = ?1 AND "
        "replica_id = ?2");
    give.bind_int64(1, static_cast<std::int64_t>(map))
        .bind_int64(2, static_cast<std::int64_t>(registry_.id()))
        .bind_int64(3, static_cast<std::int64_t>(to))
        .bind_int64(4, unix_time_ns());
    give.run();
    return give.changes() > 0;
  });
  if (!given) return false;
  std::lock_guard lock_ready(mutex_);
  ready_.erase(map);
  given_.insert(map);
  return true;
}

std::unordered_set<MapId> MapOwnership::writable(SqlConnection& db, const std::vector<MapId>& candidates,
                                                 const std::unordered_set<MapId>& gone) {
  std::unordered_set<MapId> out;
  if (registry_.lease_lost()) return out;
  const auto me = static_cast<std::int64_t>(registry_.id());
  const std::int64_t now = unix_time_ns();
  const auto claim = db.prepare_statement(
      "INSERT INTO map_owners(map_id, replica_id, claimed_ns) VALUES (?1, ?2, ?3) ON CONFLICT (map_id) DO NOTHING");
  for (const MapId map : candidates) {
    // A map made here is claimed by its first checkpoint; never one handed
    // over (its new owner may have merged it away, deleting its row: this
    // replica's copy is stale) or one merged away here.
    if (!made_here(map) || gone.count(map) || handed_over(map)) continue;
    claim->bind_int64(1, static_cast<std::int64_t>(map)).bind_int64(2, me).bind_int64(3, now);
    claim->run();
    claim->reset();
  }
  std::unordered_set<MapId> held;
  {
    const auto mine = db.prepare_statement("SELECT map_id FROM map_owners WHERE replica_id = ?1 FOR SHARE");
    mine->bind_int64(1, me);
    while (mine->step()) held.insert(static_cast<MapId>(mine->int64(0)));
  }
  const auto release = db.prepare_statement("DELETE FROM map_owners WHERE map_id = ?1 AND replica_id = ?2");
  for (const MapId map : candidates) {
    if (!held.count(map) || !owns(map)) continue;
    out.insert(map);
    if (gone.count(map)) {  // merged away: its rows go in this transaction, and so does its owner row
      release->bind_int64(1, static_cast<std::int64_t>(map)).bind_int64(2, me);
      release->run();
      release->reset();
    }
  }
  return out;
}

void MapOwnership::changed(SqlConnection& db, const std::vector<MapId>& maps) {
  const auto bump =
      db.prepare_statement("UPDATE map_owners SET version = version + 1 WHERE map_id = ?1 AND replica_id = ?2");
  for (const MapId map : maps) {
    bump->bind_int64(1, static_cast<std::int64_t>(map)).bind_int64(2, static_cast<std::int64_t>(registry_.id()));
    bump->run();
    bump->reset();
  }
}

std::vector<MapOwnership::Owned> MapOwnership::owners() const {
  std::lock_guard lock(db_mutex_);
  std::vector<Owned> out;
  on_pg_connection(db_, location_, [&](PgDb& db) {
    PgStatement rows = db.prepare("SELECT map_id, replica_id, version FROM map_owners ORDER BY map_id");
    while (rows.step())
      out.push_back({static_cast<MapId>(rows.int64(0)), static_cast<std::uint64_t>(rows.int64(1)), rows.int64(2)});
  });
  return out;
}

}  // namespace orbatlas
