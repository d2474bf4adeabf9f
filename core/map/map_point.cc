#include "core/map/map_point.h"

#include <algorithm>

#include "core/common/error.h"
#include "core/map/keyframe.h"
#include "core/map/redundancy_tracker.h"

namespace orbatlas {

std::shared_ptr<MapPoint> MapPoint::create(MapPointId id, MapId map, MapPointData data,
                                           std::shared_ptr<ObjectCounters> counters) {
  // Not make_shared: with a separate allocation the object's memory is freed when
  // the last strong reference drops, even while weak references remain.
  return std::shared_ptr<MapPoint>(new MapPoint(id, map, std::move(data), std::move(counters)));
}

MapPoint::MapPoint(MapPointId id, MapId map, MapPointData data, std::shared_ptr<ObjectCounters> counters)
    : token_(std::move(counters), ObjectKind::map_point), id_(id), map_id_(map), data_(std::move(data)) {}

Eigen::Vector3d MapPoint::p_w() const {
  std::lock_guard lock(mutex_);
  return data_.p_w;
}

void MapPoint::set_p_w(const Eigen::Vector3d& p_w) {
  std::lock_guard lock(mutex_);
  data_.p_w = p_w;
}

Descriptor MapPoint::descriptor() const {
  std::lock_guard lock(mutex_);
  return data_.descriptor;
}

void MapPoint::set_descriptor(const Descriptor& descriptor) {
  std::lock_guard lock(mutex_);
  data_.descriptor = descriptor;
}

Eigen::Vector3d MapPoint::normal() const {
  std::lock_guard lock(mutex_);
  return data_.normal;
}

void MapPoint::set_normal(const Eigen::Vector3d& normal) {
  std::lock_guard lock(mutex_);
  data_.normal = normal;
}

float MapPoint::min_distance() const {
  std::lock_guard lock(mutex_);
  return data_.min_distance;
}

float MapPoint::max_distance() const {
  std::lock_guard lock(mutex_);
  return data_.max_distance;
}

MapPoint::Geometry MapPoint::geometry() const {
  std::lock_guard lock(mutex_);
  return {data_.p_w, data_.normal, data_.min_distance, data_.max_distance};
}

void MapPoint::set_distances(float min_distance, float max_distance) {
  ORBATLAS_CHECK(min_distance <= max_distance,
                 "map point " << id_ << ": min distance " << min_distance << " > max distance " << max_distance);
  std::lock_guard lock(mutex_);
  data_.min_distance = min_distance;
  data_.max_distance = max_distance;
}

std::shared_ptr<KeyFrame> MapPoint::reference_keyframe() const {
  std::lock_guard lock(mutex_);
  return reference_.lock();
}

std::optional<KeyframeId> MapPoint::reference_keyframe_id() const {
  std::lock_guard lock(mutex_);
  return reference_id_;
}

void MapPoint::set_reference_keyframe(const std::shared_ptr<KeyFrame>& keyframe) {
  std::lock_guard lock(mutex_);
  reference_ = keyframe;
  reference_id_ = keyframe ? std::optional<KeyframeId>(keyframe->id()) : std::nullopt;
}

double MapPoint::found_ratio() const {
  return static_cast<double>(found_.load()) / static_cast<double>(std::max(1, visible_.load()));
}

std::vector<MapPointObservation> MapPoint::observations() const {
  std::lock_guard lock(mutex_);
  std::vector<MapPointObservation> out;
  out.reserve(observers_.size());
  for (const auto& [kf_id, record] : observers_) out.push_back({kf_id, record.keyframe, record.slot, record.level});
  return out;
}

std::size_t MapPoint::observation_count() const {
  std::lock_guard lock(mutex_);
  return observers_.size();
}

std::optional<std::size_t> MapPoint::slot_in(KeyframeId keyframe) const {
  std::lock_guard lock(mutex_);
  const auto it = observers_.find(keyframe);
  if (it == observers_.end()) return std::nullopt;
  return it->second.slot;
}

int MapPoint::observers_up_to_level(int max_level, KeyframeId exclude, int enough) const {
  std::lock_guard lock(mutex_);
  int n = 0;
  for (const auto& [kf_id, record] : observers_) {
    if (kf_id == exclude || record.level > max_level) continue;
    if (++n >= enough) break;
  }
  return n;
}

const char* to_string(SlotEdit edit) {
  switch (edit) {
    case SlotEdit::kDone:
      return "done";
    case SlotEdit::kBad:
      return "culled";
    case SlotEdit::kSlotTaken:
      return "slot taken";
    case SlotEdit::kSlotChanged:
      return "slot changed";
    case SlotEdit::kAlreadyObserved:
      return "already observed";
  }
  return "?";
}

SlotEdit MapPoint::attach_observer(KeyframeId keyframe, ObserverRecord record) {
  std::lock_guard lock(mutex_);
  if (bad_.load()) return SlotEdit::kBad;
  if (observers_.contains(keyframe)) return SlotEdit::kAlreadyObserved;
  if (!reference_id_) {
    reference_ = record.keyframe;
    reference_id_ = keyframe;
  }
  track_attach(observers_, keyframe, std::move(record));
  return SlotEdit::kDone;
}

void MapPoint::detach_observer(KeyframeId keyframe) {
  std::lock_guard lock(mutex_);
  track_detach(observers_, keyframe);
  if (reference_id_ == keyframe) {
    reference_.reset();
    reference_id_.reset();
    if (!observers_.empty()) {
      reference_ = observers_.begin()->second.keyframe;
      reference_id_ = observers_.begin()->first;
    }
  }
}

void MapPoint::mark_bad() {
  std::lock_guard lock(mutex_);
  bad_.store(true);
}

}  // namespace orbatlas
