#pragma once
// The merge work finished sessions leave in a shared (PostgreSQL) atlas
// (issue 23, schema/postgres/006, docs/scaling.md "Replicas"): one row per map
// to search for a place shared with the atlas's other maps (then merged and
// refined, MapMergeWorker). The replica owning the map does it and deletes the
// row; when it dies first, the replica that takes its maps over takes their
// rows too (AtlasService::take_over_maps). A replica started with
// --no-merging leaves its rows to one that merges.
//
// Thread-safe: one connection under a mutex.
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "core/common/ids.h"
#include "core/optimization/global_bundle_adjustment.h"
#include "core/server/atlas_service.h"

namespace orbatlas {

class PgDb;

// What a MergeRequest needs besides its camera (made again from `settings`).
struct StoredMerge {
  MapId map = 0;
  SettingsSource settings;
  KeyframeId first_keyframe = 0;
  std::optional<GlobalBundleAdjustmentOptions::Inertial> inertial;
  bool single_camera = false;
};

// As stored (JSON) and back (DataError on a malformed one).
std::string stored_merge_json(const StoredMerge& merge);
StoredMerge stored_merge_from_json(MapId map, const std::string& text);

class SharedMerges {
 public:
  explicit SharedMerges(std::string location);
  ~SharedMerges();
  SharedMerges(const SharedMerges&) = delete;
  SharedMerges& operator=(const SharedMerges&) = delete;

  void add(const StoredMerge& merge);  // replaces the map's row
  void remove(MapId map);
  std::vector<StoredMerge> of(const std::vector<MapId>& maps);  // the rows of these maps

 private:
  const std::string location_;
  std::mutex mutex_;  // a leaf; guards db_
  std::unique_ptr<PgDb> db_;
};

}  // namespace orbatlas
