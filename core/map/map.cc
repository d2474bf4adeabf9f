// Map: containers and snapshots (culling is in map_culling.cc).
#include "core/map/map.h"

#include <algorithm>

#include "core/common/error.h"

namespace orbatlas {

Map::Map(MapId id, std::shared_ptr<IdAllocator> ids, std::shared_ptr<ObjectCounters> counters)
    : id_(id), ids_(std::move(ids)), counters_(std::move(counters)) {
  ORBATLAS_CHECK(ids_ && counters_, "map " << id << " created without id allocator or counters");
}

std::shared_ptr<KeyFrame> Map::new_keyframe(KeyFrameData data) {
  auto kf = KeyFrame::create(ids_->next_keyframe_id(), id_, std::move(data), counters_);
  add_keyframe(kf);
  return kf;
}

std::shared_ptr<MapPoint> Map::new_map_point(MapPointData data) {
  auto mp = MapPoint::create(ids_->next_map_point_id(), id_, std::move(data), counters_);
  add_map_point(mp);
  return mp;
}

void Map::add_keyframe(std::shared_ptr<KeyFrame> keyframe) {
  ORBATLAS_CHECK(keyframe != nullptr, "map " << id_ << ": null keyframe");
  ORBATLAS_CHECK(keyframe->map_id() == id_, "keyframe " << keyframe->id() << " belongs to map " << keyframe->map_id()
                                                        << ", not " << id_);
  ORBATLAS_CHECK(!keyframe->is_bad(), "map " << id_ << ": keyframe " << keyframe->id() << " is culled");
  const KeyframeId kf_id = keyframe->id();
  std::lock_guard lock(objects_mutex_);
  const bool inserted = keyframes_.try_emplace(kf_id, std::move(keyframe)).second;
  ORBATLAS_CHECK(inserted, "map " << id_ << ": keyframe id " << kf_id << " already present");
}

void Map::add_map_point(std::shared_ptr<MapPoint> map_point) {
  ORBATLAS_CHECK(map_point != nullptr, "map " << id_ << ": null map point");
  ORBATLAS_CHECK(map_point->map_id() == id_, "map point " << map_point->id() << " belongs to map "
                                                          << map_point->map_id() << ", not " << id_);
  ORBATLAS_CHECK(!map_point->is_bad(), "map " << id_ << ": map point " << map_point->id() << " is culled");
  const MapPointId mp_id = map_point->id();
  std::lock_guard lock(objects_mutex_);
  const bool inserted = map_points_.try_emplace(mp_id, std::move(map_point)).second;
  ORBATLAS_CHECK(inserted, "map " << id_ << ": map point id " << mp_id << " already present");
}

std::shared_ptr<KeyFrame> Map::keyframe(KeyframeId id) const {
  std::lock_guard lock(objects_mutex_);
  const auto it = keyframes_.find(id);
  return it == keyframes_.end() ? nullptr : it->second;
}

std::shared_ptr<MapPoint> Map::map_point(MapPointId id) const {
  std::lock_guard lock(objects_mutex_);
  const auto it = map_points_.find(id);
  return it == map_points_.end() ? nullptr : it->second;
}

namespace {

template <class Object, class Container>
std::vector<std::shared_ptr<Object>> copy_values(const Container& container) {
  std::vector<std::shared_ptr<Object>> out;
  out.reserve(container.size());
  for (const auto& [id, object] : container) out.push_back(object);
  return out;
}

template <class Object>
void sort_by_id(std::vector<std::shared_ptr<Object>>& objects) {
  std::sort(objects.begin(), objects.end(), [](const auto& a, const auto& b) { return a->id() < b->id(); });
}

}  // namespace

std::vector<std::shared_ptr<KeyFrame>> Map::keyframes() const {
  std::vector<std::shared_ptr<KeyFrame>> out;
  {
    std::lock_guard lock(objects_mutex_);
    out = copy_values<KeyFrame>(keyframes_);
  }
  sort_by_id(out);
  return out;
}

std::vector<std::shared_ptr<MapPoint>> Map::map_points() const {
  std::vector<std::shared_ptr<MapPoint>> out;
  {
    std::lock_guard lock(objects_mutex_);
    out = copy_values<MapPoint>(map_points_);
  }
  sort_by_id(out);
  return out;
}

std::size_t Map::keyframe_count() const {
  std::lock_guard lock(objects_mutex_);
  return keyframes_.size();
}

std::size_t Map::map_point_count() const {
  std::lock_guard lock(objects_mutex_);
  return map_points_.size();
}

std::vector<Map::CulledKeyframe> Map::culled_keyframes() const {
  std::vector<CulledKeyframe> out;
  {
    std::lock_guard lock(objects_mutex_);  // culling records anchors under it
    out.reserve(culled_anchors_.size());
    for (const auto& [id, anchor] : culled_anchors_) out.push_back({id, anchor.parent, anchor.T_parent_b});
  }
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.id < b.id; });
  return out;
}

void Map::restore_culled_keyframes(const std::vector<CulledKeyframe>& culled) {
  std::lock_guard lock(objects_mutex_);
  for (const CulledKeyframe& c : culled) {
    ORBATLAS_CHECK(!keyframes_.contains(c.id), "map " << id_ << ": culled keyframe " << c.id << " is alive here");
    const bool inserted = culled_anchors_.try_emplace(c.id, CulledAnchor{c.parent, c.T_parent_b}).second;
    ORBATLAS_CHECK(inserted, "map " << id_ << ": culled keyframe " << c.id << " restored twice");
  }
}

}  // namespace orbatlas
