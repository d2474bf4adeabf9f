#include "core/map/atlas.h"

#include <utility>

#include "core/common/error.h"

namespace orbatlas {

Atlas::Atlas() : ids_(std::make_shared<IdAllocator>()), counters_(std::make_shared<ObjectCounters>()) {}

std::shared_ptr<Map> Atlas::create_map() {
  auto map = std::make_shared<Map>(ids_->next_map_id(), ids_, counters_);
  std::lock_guard lock(mutex_);
  maps_.emplace(map->id(), map);
  active_ = map;
  return map;
}

std::shared_ptr<Map> Atlas::add_map(MapId id) {
  ids_->ensure_above(IdKind::map, id);
  auto map = std::make_shared<Map>(id, ids_, counters_);
  std::lock_guard lock(mutex_);
  const bool inserted = maps_.try_emplace(id, map).second;
  ORBATLAS_CHECK(inserted, "atlas already has a map " << id);
  return map;
}

void Atlas::set_active(MapId id) {
  std::lock_guard lock(mutex_);
  const auto it = maps_.find(id);
  ORBATLAS_CHECK(it != maps_.end(), "atlas has no map " << id);
  active_ = it->second;
}

std::shared_ptr<Map> Atlas::active_map() const {
  std::lock_guard lock(mutex_);
  return active_;
}

std::shared_ptr<Map> Atlas::map(MapId id) const {
  std::lock_guard lock(mutex_);
  const auto it = maps_.find(id);
  return it == maps_.end() ? nullptr : it->second;
}

std::vector<std::shared_ptr<Map>> Atlas::maps() const {
  std::lock_guard lock(mutex_);
  std::vector<std::shared_ptr<Map>> out;
  for (const auto& [id, map] : maps_) out.push_back(map);
  return out;
}

std::size_t Atlas::index_all_keyframes() {
  for (const auto& map : maps())
    for (const auto& keyframe : map->keyframes()) index_.add(keyframe);
  return index_.size();
}

std::optional<Pose3> Atlas::frame_pose(const FrameAnchor& anchor) const {
  const auto located = locate_frame(anchor);
  if (!located) return std::nullopt;
  return located->second;
}

std::optional<std::pair<MapId, Pose3>> Atlas::locate_frame(const FrameAnchor& anchor) const {
  // The anchor's translation is in its reference keyframe's units (FrameAnchor).
  const auto place = [&](const Map::KeyframePlacement& ref) {
    Pose3 T_ref_b = anchor.T_ref_b;
    T_ref_b.t *= ref.units;
    return ref.T_w_b * T_ref_b;
  };
  if (const auto m = map(anchor.map))
    if (const auto ref = m->keyframe_placement(anchor.reference)) return std::pair{m->id(), place(*ref)};
  // A merge moved the reference keyframe into another map.
  for (const auto& m : maps())
    if (const auto ref = m->keyframe_placement(anchor.reference)) return std::pair{m->id(), place(*ref)};
  return std::nullopt;
}

std::optional<MapId> Atlas::map_holding(KeyframeId keyframe) const {
  for (const auto& m : maps())
    if (m->keyframe_pose(keyframe)) return m->id();
  return std::nullopt;
}

std::shared_ptr<Map> Atlas::remove_map(MapId id) {
  std::lock_guard lock(mutex_);
  const auto it = maps_.find(id);
  if (it == maps_.end()) return nullptr;
  auto removed = std::move(it->second);
  maps_.erase(it);
  removed_.push_back(id);
  if (active_ == removed) active_.reset();
  return removed;
}

std::shared_ptr<Map> Atlas::detached_map(MapId id) const { return std::make_shared<Map>(id, ids_, counters_); }

std::shared_ptr<Map> Atlas::replace_map(std::shared_ptr<Map> map) {
  ORBATLAS_CHECK(map != nullptr, "atlas: replace_map needs a map");
  std::lock_guard lock(mutex_);
  std::shared_ptr<Map>& slot = maps_[map->id()];
  std::shared_ptr<Map> old = std::exchange(slot, map);
  if (old && active_ == old) active_ = std::move(map);
  return old;
}

std::vector<MapId> Atlas::removed_maps() const {
  std::lock_guard lock(mutex_);
  return removed_;
}

}  // namespace orbatlas
