// KeyFrame: construction, pose and the observation slots (both sides).
#include "core/map/keyframe.h"

#include <algorithm>
#include <cmath>

#include "core/common/error.h"

namespace orbatlas {

std::shared_ptr<KeyFrame> KeyFrame::create(KeyframeId id, MapId map, KeyFrameData data,
                                           std::shared_ptr<ObjectCounters> counters) {
  const std::size_t n = data.features.keypoints.size();
  ORBATLAS_CHECK(data.depth.empty() || data.depth.size() == n,
                 "keyframe " << id << ": " << data.depth.size() << " depths for " << n << " keypoints");
  ORBATLAS_CHECK(data.u_right.size() == data.depth.size(), "keyframe " << id << ": " << data.u_right.size()
                                                                       << " right columns for " << data.depth.size()
                                                                       << " depths");
  ORBATLAS_CHECK(
      data.features.descriptors.empty() || data.features.descriptors.size() == n,
      "keyframe " << id << ": " << data.features.descriptors.size() << " descriptors for " << n << " keypoints");
  ORBATLAS_CHECK(n <= UINT32_MAX, "keyframe " << id << ": too many keypoints");
  // Not make_shared: with a separate allocation the object's memory is freed when
  // the last strong reference drops, even while weak references remain.
  return std::shared_ptr<KeyFrame>(new KeyFrame(id, map, std::move(data), std::move(counters)));
}

KeyFrame::KeyFrame(KeyframeId id, MapId map, KeyFrameData data, std::shared_ptr<ObjectCounters> counters)
    : token_(std::move(counters), ObjectKind::keyframe),
      id_(id),
      map_id_(map),
      data_(std::move(data)),
      has_depth_(std::any_of(data_.depth.begin(), data_.depth.end(), [](float d) { return d > 0.0f; })),
      redundant_(std::make_shared<std::atomic<int>>(0)),
      T_w_b_(data_.T_w_b),
      slots_(data_.features.keypoints.size()),
      slot_ids_(slots_.size(), kInvalidMapPointId) {}

KeyFrame::~KeyFrame() {
  // Nobody else can reach this keyframe any more (weak links fail to lock), but
  // the points it still observes list it: remove those records so observer lists
  // and redundancy counts stay exact. The points' destructors (if this was their
  // last owner) run after this body, when slots_ is destroyed, with no lock held.
  for (const auto& mp : slots_)
    if (mp) mp->detach_observer(id_);
}

void KeyFrame::check_slot(std::size_t slot) const {
  ORBATLAS_CHECK(slot < slot_count(),
                 "keyframe " << id_ << ": slot " << slot << " out of range (" << slot_count() << ")");
}

const Keypoint& KeyFrame::keypoint(std::size_t slot) const {
  check_slot(slot);
  return data_.features.keypoints[slot];
}

float KeyFrame::depth(std::size_t slot) const {
  check_slot(slot);
  return data_.depth.empty() ? -1.0f : data_.depth[slot];
}

float KeyFrame::u_right(std::size_t slot) const {
  check_slot(slot);
  return data_.u_right.empty() ? -1.0f : data_.u_right[slot];
}

Pose3 KeyFrame::T_w_b() const {
  std::lock_guard lock(mutex_);
  return T_w_b_;
}

Pose3 KeyFrame::T_w_c() const { return T_w_b() * data_.T_b_c; }

void KeyFrame::set_T_w_b(const Pose3& T_w_b) {
  std::lock_guard lock(mutex_);
  T_w_b_ = T_w_b;
}

double KeyFrame::units() const {
  std::lock_guard lock(mutex_);
  return units_;
}

void KeyFrame::scale_units(double factor) {
  ORBATLAS_CHECK(std::isfinite(factor) && factor > 0.0,
                 "keyframe " << id_ << ": units are scaled by a finite factor > 0, not " << factor);
  std::lock_guard lock(mutex_);
  units_ *= factor;
}

void KeyFrame::set_units(double units) {
  ORBATLAS_CHECK(std::isfinite(units) && units > 0.0,
                 "keyframe " << id_ << ": units must be finite and > 0, not " << units);
  std::lock_guard lock(mutex_);
  units_ = units;
}

SlotEdit KeyFrame::attach_locked(std::size_t slot, const std::shared_ptr<MapPoint>& map_point) {
  ObserverRecord record;
  record.keyframe = weak_from_this();
  record.slot = static_cast<std::uint32_t>(slot);
  record.level = data_.features.keypoints[slot].level;
  record.redundant_counter = redundant_;
  return map_point->attach_observer(id_, std::move(record));
}

SlotEdit KeyFrame::try_add_observation(std::size_t slot, const std::shared_ptr<MapPoint>& map_point) {
  ORBATLAS_CHECK(map_point != nullptr, "keyframe " << id_ << ": null map point for slot " << slot);
  check_slot(slot);
  std::lock_guard lock(mutex_);
  if (bad_.load()) return SlotEdit::kBad;
  if (slots_[slot]) return SlotEdit::kSlotTaken;
  const SlotEdit attached = attach_locked(slot, map_point);
  if (attached != SlotEdit::kDone) return attached;
  slots_[slot] = map_point;
  slot_ids_[slot] = map_point->id();
  map_point_count_.fetch_add(1);
  return SlotEdit::kDone;
}

bool KeyFrame::add_observation(std::size_t slot, const std::shared_ptr<MapPoint>& map_point) {
  const SlotEdit edit = try_add_observation(slot, map_point);
  ORBATLAS_CHECK(edit != SlotEdit::kSlotTaken, "keyframe " << id_ << ": slot " << slot << " already holds a map point");
  ORBATLAS_CHECK(edit != SlotEdit::kAlreadyObserved,
                 "map point " << map_point->id() << " is already observed by keyframe " << id_);
  return edit == SlotEdit::kDone;
}

std::shared_ptr<MapPoint> KeyFrame::erase_slot(std::size_t slot) {
  check_slot(slot);
  std::shared_ptr<MapPoint> released;  // returned: never dropped under our lock
  {
    std::lock_guard lock(mutex_);
    released = std::move(slots_[slot]);
    slots_[slot].reset();
    if (!released) return nullptr;
    slot_ids_[slot] = kInvalidMapPointId;
    released->detach_observer(id_);
    map_point_count_.fetch_sub(1);
  }
  return released;
}

void KeyFrame::erase_slot_if_holds(std::size_t slot, const std::shared_ptr<MapPoint>& map_point) {
  std::shared_ptr<MapPoint> released;  // declared before the lock: dropped after unlocking
  std::lock_guard lock(mutex_);
  if (slot >= slots_.size() || slots_[slot] != map_point) return;
  released = std::move(slots_[slot]);
  slots_[slot].reset();
  slot_ids_[slot] = kInvalidMapPointId;
  released->detach_observer(id_);
  map_point_count_.fetch_sub(1);
}

SlotEdit KeyFrame::swap_locked(std::size_t slot, const std::shared_ptr<MapPoint>& expected, bool any,
                               const std::shared_ptr<MapPoint>& map_point, std::shared_ptr<MapPoint>& released) {
  if (!any && slots_[slot] != expected) return SlotEdit::kSlotChanged;
  if (slots_[slot] == map_point) return SlotEdit::kDone;
  if (bad_.load()) return SlotEdit::kBad;
  // Attach the new point first: if that fails or throws, nothing has changed.
  const SlotEdit attached = attach_locked(slot, map_point);
  if (attached != SlotEdit::kDone) return attached;
  released = std::move(slots_[slot]);
  if (released) {
    released->detach_observer(id_);
  } else {
    map_point_count_.fetch_add(1);
  }
  slots_[slot] = map_point;
  slot_ids_[slot] = map_point->id();
  return SlotEdit::kDone;
}

SlotEdit KeyFrame::replace_if_holds(std::size_t slot, const std::shared_ptr<MapPoint>& expected,
                                    const std::shared_ptr<MapPoint>& replacement) {
  ORBATLAS_CHECK(replacement != nullptr, "keyframe " << id_ << ": null map point for slot " << slot);
  check_slot(slot);
  std::shared_ptr<MapPoint> released;  // declared before the lock: dropped after unlocking
  std::lock_guard lock(mutex_);
  return swap_locked(slot, expected, false, replacement, released);
}

bool KeyFrame::replace(std::size_t slot, const std::shared_ptr<MapPoint>& map_point) {
  ORBATLAS_CHECK(map_point != nullptr, "keyframe " << id_ << ": null map point for slot " << slot);
  check_slot(slot);
  std::shared_ptr<MapPoint> released;  // declared before the lock: dropped after unlocking
  std::lock_guard lock(mutex_);
  const SlotEdit edit = swap_locked(slot, nullptr, true, map_point, released);
  ORBATLAS_CHECK(edit != SlotEdit::kAlreadyObserved,
                 "map point " << map_point->id() << " is already observed by keyframe " << id_);
  return edit == SlotEdit::kDone;
}

std::shared_ptr<MapPoint> KeyFrame::map_point(std::size_t slot) const {
  check_slot(slot);
  std::lock_guard lock(mutex_);
  return slots_[slot];
}

std::vector<std::shared_ptr<MapPoint>> KeyFrame::slots() const {
  std::lock_guard lock(mutex_);
  return slots_;
}

std::vector<std::shared_ptr<MapPoint>> KeyFrame::map_points() const {
  std::lock_guard lock(mutex_);
  std::vector<std::shared_ptr<MapPoint>> out;
  out.reserve(static_cast<std::size_t>(map_point_count_.load()));
  for (const auto& mp : slots_)
    if (mp) out.push_back(mp);
  return out;
}

void KeyFrame::mark_bad() {
  std::lock_guard lock(mutex_);
  bad_.store(true);
}

double median_scene_depth(const KeyFrame& keyframe) {
  const Pose3 T_c_w = keyframe.T_w_c().inverse();
  std::vector<double> depths;
  for (const auto& mp : keyframe.map_points())
    if (!mp->is_bad()) depths.push_back((T_c_w * mp->p_w()).z());
  if (depths.empty()) return -1.0;
  std::nth_element(depths.begin(), depths.begin() + static_cast<std::ptrdiff_t>(depths.size() / 2), depths.end());
  return depths[depths.size() / 2];
}

}  // namespace orbatlas
