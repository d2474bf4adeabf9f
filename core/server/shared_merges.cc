#include "core/server/shared_merges.h"

#include <nlohmann/json.hpp>

#include "core/common/error.h"
#include "core/persistence/pg_db.h"
#include "core/persistence/wall_clock.h"
#include "core/server/pg_connection.h"

namespace orbatlas {

std::string stored_merge_json(const StoredMerge& m) {
  nlohmann::json j = {{"config", m.settings.config},
                      {"settings_yaml", m.settings.settings_yaml},
                      {"first_keyframe", m.first_keyframe},
                      {"single_camera", m.single_camera},
                      {"inertial", nullptr}};
  if (m.inertial) {
    const Pose3& T = m.inertial->T_b_i;
    j["inertial"] = {{"T_b_i", {T.q.w(), T.q.x(), T.q.y(), T.q.z(), T.t.x(), T.t.y(), T.t.z()}},
                     {"max_chain_keyframes", m.inertial->max_chain_keyframes},
                     {"huber", m.inertial->huber}};
  }
  return j.dump();
}

StoredMerge stored_merge_from_json(MapId map, const std::string& text) {
  try {
    const nlohmann::json j = nlohmann::json::parse(text);
    StoredMerge m;
    m.map = map;
    m.settings.config = j.at("config").get<std::string>();
    m.settings.settings_yaml = j.at("settings_yaml").get<std::string>();
    m.first_keyframe = j.at("first_keyframe").get<KeyframeId>();
    m.single_camera = j.at("single_camera").get<bool>();
    if (!j.at("inertial").is_null()) {
      const auto& i = j.at("inertial");
      const std::vector<double> v = i.at("T_b_i").get<std::vector<double>>();
      ORBATLAS_DATA_CHECK(v.size() == 7, "T_b_i has " << v.size() << " values, not 7");
      GlobalBundleAdjustmentOptions::Inertial inertial;
      inertial.T_b_i = Pose3(Eigen::Quaterniond(v[0], v[1], v[2], v[3]), Eigen::Vector3d(v[4], v[5], v[6]));
      inertial.max_chain_keyframes = i.at("max_chain_keyframes").get<std::size_t>();
      inertial.huber = i.at("huber").get<double>();
      m.inertial = inertial;
    }
    return m;
  } catch (const nlohmann::json::exception& e) {
    throw DataError("map " + std::to_string(map) + ": a stored merge request is not readable: " + e.what());
  }
}

// A replica counts as alive while it runs and its lease has not passed.
constexpr const char* kAliveReplicas = "SELECT id FROM replicas WHERE state = 'running' AND lease_until >= now()";

SharedMerges::SharedMerges(std::string location) : location_(std::move(location)) {}

SharedMerges::~SharedMerges() = default;

void SharedMerges::add(const StoredMerge& merge) {
  std::lock_guard lock(mutex_);
  on_pg_connection(db_, location_, [&](PgDb& db) {
    db.prepare(
          "INSERT INTO shared_merges(map_id, request, requested_ns) VALUES (?1, ?2, ?3) ON CONFLICT (map_id) DO "
          "UPDATE SET request = excluded.request, requested_ns = excluded.requested_ns, claimed_by = NULL, "
          "retry_ns = 0")
        .bind_int64(1, static_cast<std::int64_t>(merge.map))
        .bind_text(2, stored_merge_json(merge))
        .bind_int64(3, unix_time_ns())
        .run();
  });
}

void SharedMerges::remove(MapId map) {
  std::lock_guard lock(mutex_);
  on_pg_connection(db_, location_, [&](PgDb& db) {
    db.prepare("DELETE FROM shared_merges WHERE map_id = ?1").bind_int64(1, static_cast<std::int64_t>(map)).run();
  });
}

std::vector<StoredMerge> SharedMerges::of(const std::vector<MapId>& maps) {
  std::lock_guard lock(mutex_);
  return on_pg_connection(db_, location_, [&](PgDb& db) {
    std::vector<StoredMerge> out;
    PgStatement row = db.prepare("SELECT request FROM shared_merges WHERE map_id = ?1");
    for (const MapId map : maps) {
      row.bind_int64(1, static_cast<std::int64_t>(map));
      if (row.step()) out.push_back(stored_merge_from_json(map, row.text(0)));
      row.reset();
    }
    return out;
  });
}

void SharedMerges::begin_session(SessionId session, std::uint64_t replica, const StoredMerge& request) {
  std::lock_guard lock(mutex_);
  on_pg_connection(db_, location_, [&](PgDb& db) {
    db.prepare(
          "INSERT INTO shared_session_work(session_id, replica_id, request, started_ns) VALUES (?1, ?2, ?3, ?4) "
          "ON CONFLICT (session_id) DO UPDATE SET replica_id = excluded.replica_id, request = excluded.request, "
          "started_ns = excluded.started_ns")
        .bind_int64(1, static_cast<std::int64_t>(session))
        .bind_int64(2, static_cast<std::int64_t>(replica))
        .bind_text(3, stored_merge_json(request))
        .bind_int64(4, unix_time_ns())
        .run();
  });
}

void SharedMerges::end_session(SessionId session) {
  std::lock_guard lock(mutex_);
  on_pg_connection(db_, location_, [&](PgDb& db) {
    db.prepare("DELETE FROM shared_session_work WHERE session_id = ?1")
        .bind_int64(1, static_cast<std::int64_t>(session))
        .run();
  });
}

std::vector<MapId> SharedMerges::adopt_sessions_of_gone_replicas() {
  std::lock_guard lock(mutex_);
  return on_pg_connection(db_, location_, [&](PgDb& db) {
    // The DELETE locks the rows it takes: a second replica adopting at the
    // same time waits, then finds them gone.
    PgStatement adopt = db.prepare(
        std::string("WITH gone AS (DELETE FROM shared_session_work WHERE replica_id NOT IN (") + kAliveReplicas +
        ") RETURNING session_id, request) "
        "INSERT INTO shared_merges(map_id, request, requested_ns) "
        "SELECT DISTINCT ON (k.map_id) k.map_id, g.request, ?1 FROM gone g JOIN keyframes k ON k.session_id = "
        "g.session_id ORDER BY k.map_id, g.session_id "
        "ON CONFLICT (map_id) DO NOTHING RETURNING map_id");
    adopt.bind_int64(1, unix_time_ns());
    std::vector<MapId> maps;
    while (adopt.step()) maps.push_back(static_cast<MapId>(adopt.int64(0)));
    return maps;
  });
}

std::optional<StoredMerge> SharedMerges::claim(std::uint64_t me) {
  std::lock_guard lock(mutex_);
  return on_pg_connection(db_, location_, [&](PgDb& db) -> std::optional<StoredMerge> {
    PgStatement take = db.prepare(
        std::string("UPDATE shared_merges SET claimed_by = ?1 WHERE map_id = (SELECT s.map_id FROM shared_merges s "
                    "JOIN map_owners o ON o.map_id = s.map_id WHERE o.replica_id = ?1 AND s.retry_ns <= ?2 AND "
                    "(s.claimed_by IS NULL OR s.claimed_by NOT IN (") +
        kAliveReplicas +
        ")) ORDER BY s.requested_ns, s.map_id LIMIT 1 FOR UPDATE OF s SKIP LOCKED) "
        "RETURNING map_id, request");
    take.bind_int64(1, static_cast<std::int64_t>(me)).bind_int64(2, unix_time_ns());
    if (!take.step()) return std::nullopt;
    return stored_merge_from_json(static_cast<MapId>(take.int64(0)), take.text(1));
  });
}

void SharedMerges::defer(MapId map, std::int64_t retry_ns) {
  std::lock_guard lock(mutex_);
  on_pg_connection(db_, location_, [&](PgDb& db) {
    db.prepare("UPDATE shared_merges SET claimed_by = NULL, retry_ns = ?2 WHERE map_id = ?1")
        .bind_int64(1, static_cast<std::int64_t>(map))
        .bind_int64(2, retry_ns)
        .run();
  });
}

void SharedMerges::unclaim(MapId map) {
  std::lock_guard lock(mutex_);
  on_pg_connection(db_, location_, [&](PgDb& db) {
    db.prepare("UPDATE shared_merges SET claimed_by = NULL WHERE map_id = ?1")
        .bind_int64(1, static_cast<std::int64_t>(map))
        .run();
  });
}

bool SharedMerges::put_off(MapId map) {
  std::lock_guard lock(mutex_);
  return on_pg_connection(db_, location_, [&](PgDb& db) {
    PgStatement row = db.prepare("SELECT retry_ns FROM shared_merges WHERE map_id = ?1");
    row.bind_int64(1, static_cast<std::int64_t>(map));
    return row.step() && row.int64(0) > 0;
  });
}

std::optional<MapId> SharedMerges::waiting_elsewhere(std::uint64_t me, std::int64_t requested_before_ns) {
  std::lock_guard lock(mutex_);
  return on_pg_connection(db_, location_, [&](PgDb& db) -> std::optional<MapId> {
    PgStatement row =
        db.prepare(std::string("SELECT s.map_id FROM shared_merges s JOIN map_owners o ON o.map_id = s.map_id "
                               "WHERE o.replica_id <> ?1 AND o.replica_id IN (") +
                   kAliveReplicas +
                   ") AND s.claimed_by IS NULL AND s.requested_ns < ?2 AND s.retry_ns = 0 "
                   "ORDER BY s.requested_ns, s.map_id LIMIT 1");
    row.bind_int64(1, static_cast<std::int64_t>(me)).bind_int64(2, requested_before_ns);
    if (!row.step()) return std::nullopt;
    return static_cast<MapId>(row.int64(0));
  });
}

}  // namespace orbatlas
