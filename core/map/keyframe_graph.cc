// KeyFrame: covisibility, spanning tree and loop edges. Every link is weak; at
// most one keyframe mutex is held at a time, and strong references obtained from
// links are dropped only after the mutex is released.
#include <algorithm>
#include <utility>

#include "core/common/error.h"
#include "core/map/keyframe.h"

namespace orbatlas {

void KeyFrame::update_connections(int min_weight) {
  if (is_bad()) return;  // a culled keyframe must not reappear in its neighbours
  // Count shared points per other keyframe (ids ascending, so ties pick the lowest id).
  std::map<KeyframeId, Link> counts;
  for (const auto& mp : slots()) {
    if (!mp || mp->is_bad()) continue;
    mp->for_each_observer([&](KeyframeId other, const std::weak_ptr<KeyFrame>& kf) {
      if (other == id_) return;
      Link& link = counts[other];
      if (link.weight == 0) link.keyframe = kf;
      ++link.weight;
    });
  }
  std::vector<std::pair<std::shared_ptr<KeyFrame>, int>> kept;  // dropped at return, no lock held
  std::shared_ptr<KeyFrame> best;
  int best_weight = 0;
  for (const auto& [other_id, link] : counts) {
    auto other = link.keyframe.lock();
    if (!other || other->is_bad()) continue;
    if (link.weight > best_weight) {
      best_weight = link.weight;
      best = other;
    }
    if (link.weight >= min_weight) kept.emplace_back(std::move(other), link.weight);
  }
  if (kept.empty() && best) kept.emplace_back(best, best_weight);

  const auto self = shared_from_this();
  for (const auto& [other, weight] : kept) other->add_connection(self, weight);
  std::lock_guard lock(mutex_);
  if (bad_.load()) return;
  connections_.clear();
  for (const auto& [other, weight] : kept) connections_[other->id()] = Link{other, weight};
  rebuild_order_locked();
}

void KeyFrame::rebuild_order_locked() {
  ordered_.clear();
  ordered_.reserve(connections_.size());
  for (const auto& [other_id, link] : connections_) ordered_.push_back({other_id, link.weight});
  std::stable_sort(ordered_.begin(), ordered_.end(),
                   [](const CovisibilityEdge& a, const CovisibilityEdge& b) { return a.weight > b.weight; });
}

void KeyFrame::add_connection(const std::shared_ptr<KeyFrame>& other, int weight) {
  ORBATLAS_CHECK(other != nullptr && other.get() != this, "keyframe " << id_ << ": bad covisibility partner");
  ORBATLAS_CHECK(weight > 0, "keyframe " << id_ << ": covisibility weight " << weight << " to " << other->id());
  std::lock_guard lock(mutex_);
  if (bad_.load()) return;
  connections_[other->id()] = Link{other, weight};
  rebuild_order_locked();
}

void KeyFrame::erase_connection(KeyframeId other) {
  std::lock_guard lock(mutex_);
  if (connections_.erase(other) > 0) rebuild_order_locked();
}

int KeyFrame::weight(KeyframeId other) const {
  std::lock_guard lock(mutex_);
  const auto it = connections_.find(other);
  return it == connections_.end() ? 0 : it->second.weight;
}

std::vector<CovisibilityEdge> KeyFrame::connections() const {
  std::lock_guard lock(mutex_);
  return ordered_;
}

std::vector<std::shared_ptr<KeyFrame>> KeyFrame::best_covisibles(std::size_t n) const {
  std::vector<std::shared_ptr<KeyFrame>> out;
  std::lock_guard lock(mutex_);
  for (const auto& edge : ordered_) {
    if (out.size() >= n) break;
    auto other = connections_.at(edge.keyframe).keyframe.lock();
    if (other && !other->is_bad()) out.push_back(std::move(other));
  }
  return out;  // `out` outlives the lock only as the return value: nothing is dropped under it
}

void KeyFrame::set_parent(const std::shared_ptr<KeyFrame>& parent) {
  ORBATLAS_CHECK(parent.get() != this, "keyframe " << id_ << " cannot be its own parent");
  std::shared_ptr<KeyFrame> old;
  {
    std::lock_guard lock(mutex_);
    old = parent_.lock();
    parent_ = parent;
    parent_id_ = parent ? std::optional<KeyframeId>(parent->id()) : std::nullopt;
  }
  if (old && old != parent) old->erase_child(id_);
  if (parent) parent->add_child(id_, weak_from_this());
}

std::shared_ptr<KeyFrame> KeyFrame::parent() const {
  std::lock_guard lock(mutex_);
  return parent_.lock();
}

std::optional<KeyframeId> KeyFrame::parent_id() const {
  std::lock_guard lock(mutex_);
  return parent_id_;
}

std::vector<std::shared_ptr<KeyFrame>> KeyFrame::children() const {
  std::vector<std::shared_ptr<KeyFrame>> out;
  std::lock_guard lock(mutex_);
  for (const auto& [child_id, child] : children_)
    if (auto c = child.lock()) out.push_back(std::move(c));
  return out;
}

std::vector<KeyframeId> KeyFrame::child_ids() const {
  std::lock_guard lock(mutex_);
  std::vector<KeyframeId> out;
  for (const auto& [child_id, child] : children_) out.push_back(child_id);
  return out;
}

void KeyFrame::add_child(KeyframeId id, std::weak_ptr<KeyFrame> child) {
  std::lock_guard lock(mutex_);
  children_[id] = std::move(child);
}

void KeyFrame::erase_child(KeyframeId id) {
  std::lock_guard lock(mutex_);
  children_.erase(id);
}

void KeyFrame::add_loop_edge(const std::shared_ptr<KeyFrame>& other) {
  ORBATLAS_CHECK(other != nullptr && other.get() != this, "keyframe " << id_ << ": bad loop edge partner");
  {
    std::lock_guard lock(mutex_);
    loop_edges_[other->id()] = other;
  }
  std::lock_guard lock(other->mutex_);
  other->loop_edges_[id_] = weak_from_this();
}

std::vector<KeyframeId> KeyFrame::loop_edge_ids() const {
  std::lock_guard lock(mutex_);
  std::vector<KeyframeId> out;
  for (const auto& [other_id, other] : loop_edges_) out.push_back(other_id);
  return out;
}

void KeyFrame::erase_loop_edge(KeyframeId id) {
  std::lock_guard lock(mutex_);
  loop_edges_.erase(id);
}

std::map<KeyframeId, KeyFrame::Link> KeyFrame::take_connections() {
  std::lock_guard lock(mutex_);
  ordered_.clear();
  return std::exchange(connections_, {});
}

std::map<KeyframeId, std::weak_ptr<KeyFrame>> KeyFrame::take_loop_edges() {
  std::lock_guard lock(mutex_);
  return std::exchange(loop_edges_, {});
}

void KeyFrame::set_inertial_link(const std::shared_ptr<KeyFrame>& previous,
                                 std::shared_ptr<const Preintegration> from_previous, std::optional<Pose3> T_c_i) {
  ORBATLAS_CHECK(previous != nullptr && previous.get() != this && from_previous != nullptr,
                 "keyframe " << id_ << ": bad inertial link");
  {
    std::lock_guard lock(mutex_);
    inertial_ = InertialLink{previous, previous->id(), std::move(from_previous), T_c_i};
  }
  std::lock_guard lock(previous->mutex_);
  previous->inertial_next_ = weak_from_this();
}

std::optional<KeyFrame::InertialLink> KeyFrame::inertial_link() const {
  std::lock_guard lock(mutex_);
  return inertial_;
}

std::shared_ptr<KeyFrame> KeyFrame::inertial_next() const {
  std::lock_guard lock(mutex_);
  return inertial_next_.lock();
}

void KeyFrame::clear_inertial_link() {
  std::lock_guard lock(mutex_);
  inertial_.reset();
}

void KeyFrame::set_imu_state(const ImuState& state) {
  ORBATLAS_CHECK(state.v_i.allFinite() && state.bias.gyro.allFinite() && state.bias.accel.allFinite(),
                 "keyframe " << id_ << ": IMU state is not finite");
  std::lock_guard lock(mutex_);
  imu_state_ = state;
}

std::optional<KeyFrame::ImuState> KeyFrame::imu_state() const {
  std::lock_guard lock(mutex_);
  return imu_state_;
}

}  // namespace orbatlas
