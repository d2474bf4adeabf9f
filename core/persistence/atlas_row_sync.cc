#include "core/persistence/atlas_row_sync.h"

#include <algorithm>

namespace orbatlas {
namespace {

// Walks two vectors sorted by key once, calling only_old / only_new / both.
template <class T, class KeyOf, class OnlyOld, class OnlyNew, class Both>
void walk_sorted_pair(const std::vector<T>& old_rows, const std::vector<T>& new_rows, KeyOf key, OnlyOld only_old,
                      OnlyNew only_new, Both both) {
  auto a = old_rows.begin(), b = new_rows.begin();
  while (a != old_rows.end() || b != new_rows.end()) {
    if (b == new_rows.end() || (a != old_rows.end() && key(*a) < key(*b))) {
      only_old(*a++);
    } else if (a == old_rows.end() || key(*b) < key(*a)) {
      only_new(*b++);
    } else {
      both(*a, *b);
      ++a;
      ++b;
    }
  }
}

template <class T>
auto ignore() {
  return [](const T&) {};
}

constexpr auto keyframe_id = [](const KeyframeRow& r) { return r.id; };
constexpr auto point_id = [](const MapPointRow& r) { return r.id; };
constexpr auto culled_id = [](const CulledKeyframeRow& r) { return r.anchor.id; };
constexpr auto neighbour_id = [](const CovisibilityEdge& e) { return e.keyframe; };
constexpr auto edge_key = [](const LoopEdge& e) { return e; };

std::size_t occupied_slots(const KeyframeRow& row) {
  return static_cast<std::size_t>(
      std::count_if(row.slots.begin(), row.slots.end(), [](MapPointId id) { return id != kNoMapPoint; }));
}

class RowSync {
 public:
  RowSync(AtlasRowWriter& writer, const AtlasRows& before, const AtlasRows& now)
      : w_(writer), before_(before), now_(now) {}

  RowCounts run(TimestampNs saved_ns) {
    write_new_maps(saved_ns);
    delete_links();
    delete_objects();
    write_objects();
    write_links();
    delete_gone_maps();
    return counts_;
  }

 private:
  void write_new_maps(TimestampNs saved_ns) {
    for (const MapId map : now_.maps) {
      if (std::binary_search(before_.maps.begin(), before_.maps.end(), map)) continue;
      w_.upsert_map(map, saved_ns);
      ++counts_.inserted;
    }
  }

  // Last: a map merged into another has had its objects moved (their rows
  // updated above); whatever its row still owns goes with it.
  void delete_gone_maps() {
    for (const MapId map : before_.maps) {
      if (std::binary_search(now_.maps.begin(), now_.maps.end(), map)) continue;
      w_.delete_map(map);
      ++counts_.deleted;
    }
  }

  void delete_links() {
    walk_sorted_pair(
        before_.keyframes, now_.keyframes, keyframe_id,
        [&](const KeyframeRow& gone) {
          // Its observations and its own covisibility rows cascade with it.
          counts_.deleted += occupied_slots(gone) + gone.covisibility.size();
        },
        ignore<KeyframeRow>(),
        [&](const KeyframeRow& old_row, const KeyframeRow& new_row) {
          for (std::size_t slot = 0; slot < old_row.slots.size(); ++slot) {
            const MapPointId was = old_row.slots[slot];
            const MapPointId is = slot < new_row.slots.size() ? new_row.slots[slot] : kNoMapPoint;
            if (was == kNoMapPoint || was == is) continue;
            w_.delete_observation(old_row.id, slot);
            if (is == kNoMapPoint) ++counts_.deleted;  // otherwise re-inserted below: an update
          }
          walk_sorted_pair(
              old_row.covisibility, new_row.covisibility, neighbour_id,
              [&](const CovisibilityEdge& e) {
                w_.delete_covisibility(old_row.id, e.keyframe);
                ++counts_.deleted;
              },
              ignore<CovisibilityEdge>(), [](const CovisibilityEdge&, const CovisibilityEdge&) {});
        });
    walk_sorted_pair(
        before_.loop_edges, now_.loop_edges, edge_key,
        [&](const LoopEdge& e) {
          w_.delete_loop_edge(e);
          ++counts_.deleted;
        },
        ignore<LoopEdge>(), [](const LoopEdge&, const LoopEdge&) {});
  }

  void delete_objects() {
    walk_sorted_pair(
        before_.points, now_.points, point_id,
        [&](const MapPointRow& gone) {
          w_.delete_map_point(gone.id);
          ++counts_.deleted;
        },
        ignore<MapPointRow>(), [](const MapPointRow&, const MapPointRow&) {});
    walk_sorted_pair(
        before_.keyframes, now_.keyframes, keyframe_id,
        [&](const KeyframeRow& gone) {
          w_.delete_keyframe(gone.id);
          ++counts_.deleted;
        },
        ignore<KeyframeRow>(), [](const KeyframeRow&, const KeyframeRow&) {});
    walk_sorted_pair(
        before_.culled, now_.culled, culled_id,
        [&](const CulledKeyframeRow& gone) {
          w_.delete_culled_keyframe(gone.anchor.id);
          ++counts_.deleted;
        },
        ignore<CulledKeyframeRow>(), [](const CulledKeyframeRow&, const CulledKeyframeRow&) {});
  }

  // Keyframes, then map points and culled keyframes (whose ids the keyframe
  // rows deleted above may have held).
  void write_objects() {
    walk_sorted_pair(
        before_.keyframes, now_.keyframes, keyframe_id, ignore<KeyframeRow>(),
        [&](const KeyframeRow& added) {
          w_.insert_keyframe(added);
          ++counts_.inserted;
          if (added.inertial_previous) w_.write_inertial_link(added);  // its previous keyframe is deferred
          if (added.imu) w_.write_imu_state(added);
        },
        [&](const KeyframeRow& old_row, const KeyframeRow& new_row) {
          if (old_row.inertial_previous != new_row.inertial_previous ||
              old_row.inertial_hash != new_row.inertial_hash) {
            w_.write_inertial_link(new_row);
            ++counts_.updated;
          }
          if (old_row.imu.has_value() != new_row.imu.has_value() || old_row.imu_hash != new_row.imu_hash) {
            w_.write_imu_state(new_row);
            ++counts_.updated;
          }
          if (old_row.hash == new_row.hash) return;
          w_.update_keyframe(new_row);
          ++counts_.updated;
        });
    walk_sorted_pair(
        before_.inertial, now_.inertial, [](const MapInertialRow& r) { return r.map; },
        [&](const MapInertialRow& gone) {
          w_.delete_map_inertial(gone.map);
          ++counts_.deleted;
        },
        [&](const MapInertialRow& added) {
          w_.upsert_map_inertial(added);
          ++counts_.inserted;
        },
        [&](const MapInertialRow& old_row, const MapInertialRow& new_row) {
          if (old_row.hash == new_row.hash) return;
          w_.upsert_map_inertial(new_row);
          ++counts_.updated;
        });
    walk_sorted_pair(
        before_.points, now_.points, point_id, ignore<MapPointRow>(),
        [&](const MapPointRow& added) {
          w_.upsert_map_point(added);
          ++counts_.inserted;
        },
        [&](const MapPointRow& old_row, const MapPointRow& new_row) {
          if (old_row.hash == new_row.hash) return;
          w_.upsert_map_point(new_row);
          ++counts_.updated;
        });
    walk_sorted_pair(
        before_.culled, now_.culled, culled_id, ignore<CulledKeyframeRow>(),
        [&](const CulledKeyframeRow& added) {
          w_.upsert_culled_keyframe(added);
          ++counts_.inserted;
        },
        [&](const CulledKeyframeRow& old_row, const CulledKeyframeRow& new_row) {
          if (old_row.hash == new_row.hash) return;
          w_.upsert_culled_keyframe(new_row);
          ++counts_.updated;
        });
  }

  void write_links() {
    walk_sorted_pair(
        before_.keyframes, now_.keyframes, keyframe_id, ignore<KeyframeRow>(),
        [&](const KeyframeRow& added) {
          for (std::size_t slot = 0; slot < added.slots.size(); ++slot) {
            if (added.slots[slot] == kNoMapPoint) continue;
            w_.insert_observation(added.id, slot, added.slots[slot]);
            ++counts_.inserted;
          }
          for (const CovisibilityEdge& e : added.covisibility) {
            w_.upsert_covisibility(added.id, e);
            ++counts_.inserted;
          }
        },
        [&](const KeyframeRow& old_row, const KeyframeRow& new_row) {
          for (std::size_t slot = 0; slot < new_row.slots.size(); ++slot) {
            const MapPointId is = new_row.slots[slot];
            const MapPointId was = slot < old_row.slots.size() ? old_row.slots[slot] : kNoMapPoint;
            if (is == kNoMapPoint || is == was) continue;
            w_.insert_observation(new_row.id, slot, is);
            ++(was == kNoMapPoint ? counts_.inserted : counts_.updated);
          }
          walk_sorted_pair(
              old_row.covisibility, new_row.covisibility, neighbour_id, ignore<CovisibilityEdge>(),
              [&](const CovisibilityEdge& e) {
                w_.upsert_covisibility(new_row.id, e);
                ++counts_.inserted;
              },
              [&](const CovisibilityEdge& old_edge, const CovisibilityEdge& new_edge) {
                if (old_edge.weight == new_edge.weight) return;
                w_.upsert_covisibility(new_row.id, new_edge);
                ++counts_.updated;
              });
        });
    walk_sorted_pair(
        before_.loop_edges, now_.loop_edges, edge_key, ignore<LoopEdge>(),
        [&](const LoopEdge& e) {
          w_.insert_loop_edge(e);
          ++counts_.inserted;
        },
        [](const LoopEdge&, const LoopEdge&) {});
  }

  AtlasRowWriter& w_;
  const AtlasRows& before_;
  const AtlasRows& now_;
  RowCounts counts_;
};

}  // namespace

RowCounts write_changed_rows(AtlasRowWriter& writer, const AtlasRows& before, const AtlasRows& now,
                             TimestampNs saved_ns) {
  return RowSync(writer, before, now).run(saved_ns);
}

bool meta_changed(const AtlasRows& before, const AtlasRows& now) {
  if (!now.meta) return false;
  return !before.meta || before.meta->hash() != now.meta->hash();
}

}  // namespace orbatlas
