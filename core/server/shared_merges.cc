#include "core/server/shared_merges.h"

#include <nlohmann/json.hpp>

#include "core/common/error.h"
#include "core/persistence/pg_db.h"
#include "core/persistence/wall_clock.h"

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

SharedMerges::SharedMerges(std::string location) : location_(std::move(location)) {}

SharedMerges::~SharedMerges() = default;

namespace {

template <class Work>
auto on_connection(std::unique_ptr<PgDb>& db, const std::string& location, Work work) {
  try {
    if (!db) db = std::make_unique<PgDb>(location);
    return work(*db);
  } catch (const std::exception&) {
    db.reset();  // a new connection next time
    throw;
  }
}

}  // namespace

void SharedMerges::add(const StoredMerge& merge) {
  std::lock_guard lock(mutex_);
  on_connection(db_, location_, [&](PgDb& db) {
    db.prepare(
          "INSERT INTO shared_merges(map_id, request, requested_ns) VALUES (?1, ?2, ?3) ON CONFLICT (map_id) DO "
          "UPDATE SET request = excluded.request, requested_ns = excluded.requested_ns")
        .bind_int64(1, static_cast<std::int64_t>(merge.map))
        .bind_text(2, stored_merge_json(merge))
        .bind_int64(3, unix_time_ns())
        .run();
  });
}

void SharedMerges::remove(MapId map) {
  std::lock_guard lock(mutex_);
  on_connection(db_, location_, [&](PgDb& db) {
    db.prepare("DELETE FROM shared_merges WHERE map_id = ?1").bind_int64(1, static_cast<std::int64_t>(map)).run();
  });
}

std::vector<StoredMerge> SharedMerges::of(const std::vector<MapId>& maps) {
  std::lock_guard lock(mutex_);
  return on_connection(db_, location_, [&](PgDb& db) {
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

}  // namespace orbatlas
