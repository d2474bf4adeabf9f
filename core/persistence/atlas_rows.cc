#include "core/persistence/atlas_rows.h"

#include <algorithm>
#include <unordered_map>

#include "core/persistence/row_hash.h"

namespace orbatlas {
namespace {

template <class Row>
void sort_rows(std::vector<Row>& rows, auto id_of) {
  std::sort(rows.begin(), rows.end(), [&](const Row& a, const Row& b) { return id_of(a) < id_of(b); });
}

class MapRowCollector {
 public:
  MapRowCollector(AtlasRows& rows, const KeyframeSessionOf& session_of) : rows_(rows), session_of_(session_of) {}

  void collect(const Map& map) {
    // The culled anchors after the keyframes: a keyframe culled in between is in
    // both and stays alive in the rows, and the parent of every anchor is then
    // either in the keyframe snapshot or an anchor itself.
    const auto keyframes = map.keyframes();  // by id
    const auto points = map.map_points();    // by id
    const auto culled = map.culled_keyframes();
    kf_ids_.clear();
    point_ids_.clear();
    for (const auto& kf : keyframes) kf_ids_.push_back(kf->id());
    for (const auto& mp : points) point_ids_.push_back(mp->id());

    for (const auto& kf : keyframes) add_keyframe(map.id(), kf);
    for (const auto& mp : points) add_point(map.id(), *mp);
    if (const auto state = map.inertial_state()) {
      MapInertialRow row{map.id(), *state, 0};
      row.hash = RowHash()
                     .add(state->initialized_at_ns)
                     .add(state->gravity_w)
                     .add(state->bias.gyro)
                     .add(state->bias.accel)
                     .add(state->keyframes)
                     .add(state->span_s)
                     .add(state->refinements)
                     .add(state->scale.gyro)
                     .add(state->scale.accel)
                     .value();
      rows_.inertial.push_back(row);
    }
    for (const Map::CulledKeyframe& c : culled) {
      if (has_keyframe(c.id)) continue;
      CulledKeyframeRow row{map.id(), c, 0};
      row.hash = RowHash().add(row.map).add(c.id).add(c.parent).add(c.T_parent_b).add(c.units).value();
      rows_.culled.push_back(row);
    }
  }

 private:
  bool has_keyframe(KeyframeId id) const { return std::binary_search(kf_ids_.begin(), kf_ids_.end(), id); }
  bool has_point(MapPointId id) const { return std::binary_search(point_ids_.begin(), point_ids_.end(), id); }

  void add_keyframe(MapId map, const std::shared_ptr<KeyFrame>& kf) {
    KeyframeRow row;
    row.id = kf->id();
    row.keyframe = kf;
    row.map = map;
    row.T_w_b = kf->T_w_b();
    row.units = kf->units();
    if (const auto parent = kf->parent_id(); parent && has_keyframe(*parent)) row.parent = parent;
    row.session = session_of_ ? session_of_(row.id) : std::nullopt;
    row.hash = RowHash().add(map).add(row.T_w_b).add(row.units).add(row.parent).value();

    const auto slots = kf->slots();
    row.slots.assign(slots.size(), kNoMapPoint);
    for (std::size_t i = 0; i < slots.size(); ++i)
      if (slots[i] && !slots[i]->is_bad() && has_point(slots[i]->id())) row.slots[i] = slots[i]->id();
    // Links to keyframes culled meanwhile (or dead links culling leaves in
    // neighbours, docs/map_model.md) are left out.
    for (const CovisibilityEdge& edge : kf->connections())
      if (has_keyframe(edge.keyframe)) row.covisibility.push_back(edge);
    sort_rows(row.covisibility, [](const CovisibilityEdge& e) { return e.keyframe; });
    if (const auto link = kf->inertial_link(); link && link->from_previous && has_keyframe(link->previous_id)) {
      row.inertial_previous = link->previous_id;
      row.inertial_increments = link->from_previous;
      row.inertial_T_c_i = link->T_c_i;
      const Preintegration& d = *link->from_previous;
      row.inertial_hash = RowHash()
                              .add(link->previous_id)
                              .add(d.dt())
                              .add(d.measurements().size())
                              .add(d.delta_p())
                              .add(d.delta_v())
                              .add(d.bias().gyro)
                              .add(d.bias().accel)
                              .add(link->T_c_i ? *link->T_c_i : Pose3())
                              .add(static_cast<std::uint64_t>(link->T_c_i.has_value()))
                              .value();
    }
    if (const auto imu = kf->imu_state()) {
      row.imu = imu;
      row.imu_hash = RowHash().add(imu->v_i).add(imu->bias.gyro).add(imu->bias.accel).value();
    }
    for (const KeyframeId other : kf->loop_edge_ids())
      if (has_keyframe(other)) rows_.loop_edges.emplace_back(std::min(row.id, other), std::max(row.id, other));
    rows_.keyframes.push_back(std::move(row));
  }

  void add_point(MapId map, const MapPoint& mp) {
    MapPointRow row;
    row.id = mp.id();
    row.map = map;
    row.data.p_w = mp.p_w();
    row.data.normal = mp.normal();
    row.data.descriptor = mp.descriptor();
    row.data.min_distance = mp.min_distance();
    row.data.max_distance = mp.max_distance();
    if (const auto ref = mp.reference_keyframe_id(); ref && has_keyframe(*ref)) row.reference = ref;
    row.visible = mp.visible();
    row.found = mp.found();
    RowHash h;
    h.add(map);
    for (int i = 0; i < 3; ++i) h.add(row.data.p_w[i]).add(row.data.normal[i]);
    for (const std::uint64_t word : row.data.descriptor) h.add(word);
    h.add(row.data.min_distance).add(row.data.max_distance).add(row.reference).add(row.visible).add(row.found);
    row.hash = h.value();
    rows_.points.push_back(std::move(row));
  }

  AtlasRows& rows_;
  const KeyframeSessionOf& session_of_;
  std::vector<KeyframeId> kf_ids_;  // of the current map's snapshot, ascending
  std::vector<MapPointId> point_ids_;
};

}  // namespace

std::uint64_t AtlasMetaRow::hash() const {
  return RowHash().add(next_keyframe_id).add(next_map_point_id).add(next_map_id).add(active_map).value();
}

void AtlasRows::drop_objects() {
  for (KeyframeRow& row : keyframes) {
    row.keyframe.reset();
    row.inertial_increments.reset();
  }
}

AtlasRows collect_atlas_rows(const Atlas& atlas, const KeyframeSessionOf& session_of) {
  AtlasRows rows;
  const auto whole = atlas.lock_maps_shared();  // no merge half-way
  // The active map before the list: it is then one of the listed maps.
  const auto active = atlas.active_map();
  // Under the same lock as the maps: merges remove maps under the exclusive one.
  rows.removed_maps = atlas.removed_maps();
  MapRowCollector collector(rows, session_of);
  for (const auto& map : atlas.maps()) {
    rows.maps.push_back(map->id());
    collector.collect(*map);
  }
  // Ids are atlas-wide: the maps' rows interleave.
  sort_rows(rows.keyframes, [](const KeyframeRow& r) { return r.id; });
  sort_rows(rows.points, [](const MapPointRow& r) { return r.id; });
  sort_rows(rows.culled, [](const CulledKeyframeRow& r) { return r.anchor.id; });
  sort_rows(rows.inertial, [](const MapInertialRow& r) { return r.map; });
  std::sort(rows.loop_edges.begin(), rows.loop_edges.end());
  rows.loop_edges.erase(std::unique(rows.loop_edges.begin(), rows.loop_edges.end()), rows.loop_edges.end());

  AtlasMetaRow meta;
  const IdAllocator& ids = atlas.ids();
  meta.next_keyframe_id = ids.peek(IdKind::keyframe);
  meta.next_map_point_id = ids.peek(IdKind::map_point);
  meta.next_map_id = ids.peek(IdKind::map);
  if (active) meta.active_map = active->id();
  rows.meta = meta;
  return rows;
}

AtlasRows rows_of_maps(AtlasRows rows, const std::function<bool(MapId)>& keep) {
  std::unordered_map<KeyframeId, MapId> keyframe_maps;
  for (const KeyframeRow& k : rows.keyframes) keyframe_maps.emplace(k.id, k.map);
  std::erase_if(rows.maps, [&](MapId m) { return !keep(m); });
  if (rows.meta && rows.meta->active_map && !keep(*rows.meta->active_map)) rows.meta->active_map.reset();
  std::erase_if(rows.keyframes, [&](const KeyframeRow& r) { return !keep(r.map); });
  std::erase_if(rows.points, [&](const MapPointRow& r) { return !keep(r.map); });
  std::erase_if(rows.culled, [&](const CulledKeyframeRow& r) { return !keep(r.map); });
  std::erase_if(rows.inertial, [&](const MapInertialRow& r) { return !keep(r.map); });
  std::erase_if(rows.loop_edges, [&](const LoopEdge& e) {
    const auto it = keyframe_maps.find(e.first);
    return it == keyframe_maps.end() || !keep(it->second);
  });
  return rows;
}

std::unordered_map<MapId, std::uint64_t> map_digests(const AtlasRows& rows) {
  std::unordered_map<MapId, RowHash> hashes;
  std::unordered_map<KeyframeId, MapId> keyframe_maps;
  for (const MapId m : rows.maps) hashes[m];
  for (const KeyframeRow& k : rows.keyframes) {
    keyframe_maps.emplace(k.id, k.map);
    RowHash& h = hashes[k.map];
    h.add(std::uint64_t{k.id}).add(k.hash).add(k.inertial_hash).add(k.imu_hash);
    for (const MapPointId p : k.slots) h.add(std::uint64_t{p});
    for (const CovisibilityEdge& e : k.covisibility) h.add(std::uint64_t{e.keyframe}).add(e.weight);
  }
  for (const MapPointRow& p : rows.points) hashes[p.map].add(std::uint64_t{p.id}).add(p.hash);
  for (const CulledKeyframeRow& c : rows.culled) hashes[c.map].add(std::uint64_t{c.anchor.id}).add(c.hash);
  for (const MapInertialRow& i : rows.inertial) hashes[i.map].add(i.hash);
  for (const LoopEdge& e : rows.loop_edges)
    if (const auto it = keyframe_maps.find(e.first); it != keyframe_maps.end())
      hashes[it->second].add(std::uint64_t{e.first}).add(std::uint64_t{e.second});
  std::unordered_map<MapId, std::uint64_t> out;
  for (const auto& [map, h] : hashes) out.emplace(map, h.value());
  return out;
}

}  // namespace orbatlas
