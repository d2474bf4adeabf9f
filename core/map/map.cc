// Map: containers and snapshots (culling is in map_culling.cc).
#include "core/map/map.h"

#include <algorithm>
#include <cmath>

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
  ORBATLAS_CHECK(keyframe->map_id() == id_,
                 "keyframe " << keyframe->id() << " belongs to map " << keyframe->map_id() << ", not " << id_);
  ORBATLAS_CHECK(!keyframe->is_bad(), "map " << id_ << ": keyframe " << keyframe->id() << " is culled");
  const KeyframeId kf_id = keyframe->id();
  const bool has_depth = keyframe->has_depth();
  std::lock_guard lock(objects_mutex_);
  const bool inserted = keyframes_.try_emplace(kf_id, std::move(keyframe)).second;
  ORBATLAS_CHECK(inserted, "map " << id_ << ": keyframe id " << kf_id << " already present");
  measured_depth_ = measured_depth_ || has_depth;
}

void Map::add_map_point(std::shared_ptr<MapPoint> map_point) {
  ORBATLAS_CHECK(map_point != nullptr, "map " << id_ << ": null map point");
  ORBATLAS_CHECK(map_point->map_id() == id_,
                 "map point " << map_point->id() << " belongs to map " << map_point->map_id() << ", not " << id_);
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
    for (const auto& [id, anchor] : culled_anchors_)
      out.push_back({id, anchor.parent, anchor.T_parent_b, anchor.units});
  }
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.id < b.id; });
  return out;
}

void Map::restore_culled_keyframes(const std::vector<CulledKeyframe>& culled) {
  std::lock_guard lock(objects_mutex_);
  for (const CulledKeyframe& c : culled) {
    ORBATLAS_CHECK(!keyframes_.contains(c.id), "map " << id_ << ": culled keyframe " << c.id << " is alive here");
    ORBATLAS_CHECK(std::isfinite(c.units) && c.units > 0.0,
                   "map " << id_ << ": culled keyframe " << c.id << " has units " << c.units);
    const bool inserted = culled_anchors_.try_emplace(c.id, CulledAnchor{c.parent, c.T_parent_b, c.units}).second;
    ORBATLAS_CHECK(inserted, "map " << id_ << ": culled keyframe " << c.id << " restored twice");
  }
}

Map::AbsorbCounts Map::absorb(Map& source, const Pose3& T_this_source) {
  ORBATLAS_CHECK(&source != this, "map " << id_ << " cannot absorb itself");
  std::scoped_lock structure(structure_mutex_, source.structure_mutex_);
  std::unordered_map<KeyframeId, std::shared_ptr<KeyFrame>> keyframes;
  std::unordered_map<MapPointId, std::shared_ptr<MapPoint>> points;
  std::unordered_map<KeyframeId, CulledAnchor> culled;
  bool source_depth = false;
  {
    std::lock_guard lock(source.objects_mutex_);
    keyframes.swap(source.keyframes_);
    points.swap(source.map_points_);
    culled.swap(source.culled_anchors_);
    source_depth = source.measured_depth_;
  }
  const Eigen::Quaterniond R = T_this_source.q;
  for (const auto& [id, kf] : keyframes) {
    kf->set_T_w_b(T_this_source * kf->T_w_b());
    kf->map_id_.store(id_);
  }
  for (const auto& [id, mp] : points) {
    mp->set_p_w(T_this_source * mp->p_w());
    mp->set_normal(R * mp->normal());
    mp->map_id_.store(id_);
  }
  for (auto& [id, anchor] : culled)
    if (!anchor.parent) anchor.T_parent_b = T_this_source * anchor.T_parent_b;  // a root: its world pose

  AbsorbCounts counts{keyframes.size(), points.size(), culled.size()};
  std::lock_guard lock(objects_mutex_);
  for (auto& [id, kf] : keyframes)
    ORBATLAS_CHECK(keyframes_.try_emplace(id, std::move(kf)).second,
                   "map " << id_ << ": keyframe id " << id << " already present");
  for (auto& [id, mp] : points)
    ORBATLAS_CHECK(map_points_.try_emplace(id, std::move(mp)).second,
                   "map " << id_ << ": map point id " << id << " already present");
  for (auto& [id, anchor] : culled) culled_anchors_.insert_or_assign(id, anchor);
  measured_depth_ = measured_depth_ || source_depth;
  return counts;
}

void Map::change_frame(const Pose3& T_new_old) {
  std::lock_guard structure(structure_mutex_);
  const Eigen::Quaterniond R = T_new_old.q;
  for (const auto& kf : keyframes()) kf->set_T_w_b(T_new_old * kf->T_w_b());
  for (const auto& mp : map_points()) {
    mp->set_p_w(T_new_old * mp->p_w());
    mp->set_normal(R * mp->normal());
  }
  {
    std::lock_guard lock(objects_mutex_);
    for (auto& [id, anchor] : culled_anchors_)
      if (!anchor.parent) anchor.T_parent_b = T_new_old * anchor.T_parent_b;  // a root: its world pose
  }
  frame_epoch_.fetch_add(1);
}

void Map::rescale(double s) {
  ORBATLAS_CHECK(std::isfinite(s) && s > 0.0, "a map is rescaled by a finite factor > 0, not " << s);
  std::lock_guard structure(structure_mutex_);
  for (const auto& kf : keyframes()) {
    Pose3 T = kf->T_w_b();
    T.t *= s;
    kf->set_T_w_b(T);
    kf->scale_units(s);
    if (auto imu = kf->imu_state()) {
      imu->v_i *= s;
      kf->set_imu_state(*imu);
    }
  }
  for (const auto& mp : map_points()) {
    mp->set_p_w(s * mp->p_w());
    mp->set_distances(static_cast<float>(s * mp->min_distance()), static_cast<float>(s * mp->max_distance()));
  }
  {
    std::lock_guard lock(objects_mutex_);
    // Anchors below a parent follow its units; a root's world pose scales.
    for (auto& [id, anchor] : culled_anchors_)
      if (!anchor.parent) {
        anchor.T_parent_b.t *= s;
        anchor.units *= s;
      }
  }
  frame_epoch_.fetch_add(1);
}

bool Map::metric_scale() const {
  std::lock_guard lock(objects_mutex_);
  return measured_depth_ || inertial_.has_value();
}

bool Map::measured_depth() const {
  std::lock_guard lock(objects_mutex_);
  return measured_depth_;
}

std::optional<Map::InertialState> Map::inertial_state() const {
  std::lock_guard lock(objects_mutex_);
  return inertial_;
}

void Map::set_inertial_state(const InertialState& state) {
  std::lock_guard lock(objects_mutex_);
  inertial_ = state;
}

void Map::clear_inertial_state(TimestampNs at_ns) {
  std::lock_guard lock(objects_mutex_);
  inertial_.reset();
  inertial_cleared_at_ns_ = at_ns;
}

TimestampNs Map::inertial_cleared_at() const {
  std::lock_guard lock(objects_mutex_);
  return inertial_cleared_at_ns_;
}

}  // namespace orbatlas
