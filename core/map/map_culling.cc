// Map: culling keyframes and map points. The object leaves the containers at
// once; then every relation is detached, so that only threads still holding a
// shared_ptr keep it alive. The last of them frees it.
#include <map>
#include <vector>

#include "core/map/map.h"

namespace orbatlas {

bool Map::cull_keyframe(KeyframeId id) {
  std::lock_guard structure(structure_mutex_);
  std::shared_ptr<KeyFrame> kf;
  {
    std::lock_guard lock(objects_mutex_);
    const auto it = keyframes_.find(id);
    if (it == keyframes_.end()) return false;
    kf = it->second;
  }
  // The anchor takes the keyframe's place in the same step: a snapshot of the
  // keyframes, then of the anchors (a checkpoint's) sees it in one or both,
  // never in neither. (Recorded after the detaching below, a checkpoint in
  // between deleted the keyframe's row without writing its anchor, and the
  // stored frames that reference it dangled until the next one; a kill then
  // left them so in the file.) Nothing below changes what the anchor holds:
  // its own pose, units and parent (its children get new parents, not it).
  CulledAnchor anchor;
  if (const auto parent = kf->parent()) {
    const double parent_units = parent->units();
    anchor.parent = parent->id();
    anchor.T_parent_b = parent->T_w_b().inverse() * kf->T_w_b();
    anchor.T_parent_b.t /= parent_units;
    anchor.units = kf->units() / parent_units;
  } else {
    anchor.T_parent_b = kf->T_w_b();
    anchor.units = kf->units();
  }
  {
    std::lock_guard lock(objects_mutex_);
    keyframes_.erase(id);
    culled_anchors_[id] = anchor;
  }
  kf->mark_bad();  // from here on, no new observation or connection is accepted
  for (const auto& [other_id, link] : kf->take_connections())
    if (auto other = link.keyframe.lock()) other->erase_connection(id);
  for (const auto& [other_id, edge] : kf->take_loop_edges())
    if (auto other = edge.lock()) other->erase_loop_edge(id);
  for (std::size_t slot = 0; slot < kf->slot_count(); ++slot) kf->erase_slot(slot);
  reattach_children(kf);
  // The inertial chain skips the culled keyframe: its successor's increments
  // start at the culled one's predecessor (both joined), or the chain breaks.
  if (const auto next = kf->inertial_next()) {
    const auto link = kf->inertial_link();
    const auto next_link = next->inertial_link();
    const auto previous = link ? link->previous.lock() : nullptr;
    if (previous && !previous->is_bad() && next_link && next_link->previous_id == id) {
      auto joined = std::make_shared<Preintegration>(*link->from_previous);
      joined->append(*next_link->from_previous);
      next->set_inertial_link(previous, std::move(joined), next_link->T_c_i);
    } else {
      next->clear_inertial_link();
    }
  }
  counters_->on_culled(ObjectKind::keyframe);
  return true;
}

// ORB-SLAM's KeyFrame::SetBadFlag: the candidates for a new parent are the culled
// keyframe's parent and the children already reattached; repeatedly, the
// (child, candidate) pair with the largest covisibility weight is linked (ties: lower
// child id, then lower candidate id). Children covisible with no candidate go to
// the parent (or become roots when the culled keyframe had none).
void Map::reattach_children(const std::shared_ptr<KeyFrame>& culled) {
  const std::shared_ptr<KeyFrame> parent = culled->parent();
  std::map<KeyframeId, std::shared_ptr<KeyFrame>> children, candidates;
  for (auto& child : culled->children())
    if (!child->is_bad()) children.emplace(child->id(), std::move(child));
  if (parent) candidates.emplace(parent->id(), parent);

  while (!children.empty()) {
    int best_weight = 0;
    std::shared_ptr<KeyFrame> best_child, best_parent;
    for (const auto& [child_id, child] : children) {
      for (const auto& [candidate_id, candidate] : candidates) {
        const int w = child->weight(candidate_id);
        if (w > best_weight) {
          best_weight = w;
          best_child = child;
          best_parent = candidate;
        }
      }
    }
    if (!best_child) break;
    best_child->set_parent(best_parent);
    candidates.emplace(best_child->id(), best_child);
    children.erase(best_child->id());
  }
  for (const auto& [child_id, child] : children) child->set_parent(parent);
  if (parent) parent->erase_child(culled->id());
  // The culled keyframe keeps its (weak) parent link and id, so poses expressed
  // relative to it can still be chained; it has no children any more.
}

std::optional<Pose3> Map::keyframe_pose(KeyframeId id) const {
  const auto placement = keyframe_placement(id);
  if (!placement) return std::nullopt;
  return placement->T_w_b;
}

std::optional<Map::KeyframePlacement> Map::keyframe_placement(KeyframeId id) const {
  // The chain of culled anchors from `id` up to a live keyframe or a root,
  // then composed from the top down (each step scaled by its parent's units).
  std::vector<CulledAnchor> chain;
  std::shared_ptr<KeyFrame> top;
  {
    std::lock_guard lock(objects_mutex_);
    for (std::size_t hops = 0;; ++hops) {
      if (hops > culled_anchors_.size()) return std::nullopt;  // a cycle: cannot happen with a tree, guarded anyway
      if (const auto it = keyframes_.find(id); it != keyframes_.end()) {
        top = it->second;
        break;
      }
      const auto anchor = culled_anchors_.find(id);
      if (anchor == culled_anchors_.end()) return std::nullopt;
      chain.push_back(anchor->second);
      if (!anchor->second.parent) break;
      id = *anchor->second.parent;
    }
  }
  KeyframePlacement placement;
  auto step = chain.rbegin();
  if (top) {
    placement = {top->T_w_b(), top->units()};
  } else {  // a root anchor: its world pose and its own units
    placement = {step->T_parent_b, step->units};
    ++step;
  }
  for (; step != chain.rend(); ++step) {
    Pose3 T = step->T_parent_b;
    T.t *= placement.units;
    placement.T_w_b = placement.T_w_b * T;
    placement.units *= step->units;
  }
  return placement;
}

bool Map::cull_map_point(MapPointId id) {
  std::lock_guard structure(structure_mutex_);
  std::shared_ptr<MapPoint> mp;
  {
    std::lock_guard lock(objects_mutex_);
    const auto it = map_points_.find(id);
    if (it == map_points_.end()) return false;
    mp = std::move(it->second);
    map_points_.erase(it);
  }
  mp->mark_bad();  // no new observer is accepted, so this snapshot is complete
  for (const auto& obs : mp->observations())
    if (auto kf = obs.kf.lock()) kf->erase_slot_if_holds(obs.slot, mp);
  counters_->on_culled(ObjectKind::map_point);
  return true;
}

}  // namespace orbatlas
