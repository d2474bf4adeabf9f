// AtlasStore::load_atlas: recreates the stored maps with their ids, inside one
// read transaction (a consistent snapshot even while another process writes).
// Objects go through the map model's own API (KeyFrame::create, add_observation,
// add_connection, set_parent, add_loop_edge), so every derived state — observer
// records, redundancy counts, children lists, ordered covisibility — is rebuilt
// by the same code that maintains it at run time.
#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

#include "core/common/error.h"
#include "core/persistence/atlas_store.h"
#include "core/persistence/blob_codec.h"
#include "core/persistence/inertial_blob.h"
#include "core/persistence/sql_columns.h"

namespace orbatlas {
namespace {

struct LoadedKeyframe {
  std::shared_ptr<KeyFrame> keyframe;
  std::optional<KeyframeId> parent;
};

class AtlasReader {
 public:
  AtlasReader(SqlConnection& db, const Vocabulary* vocabulary, AtlasLoadReport& report)
      : database_(db.description()),
        vocabulary_(vocabulary),
        report_(report),
        keyframes_(
            db.prepare_statement("SELECT id, session_id, timestamp_ns, qw, qx, qy, qz, tx, ty, tz, "
                                 "c_qw, c_qx, c_qy, c_qz, c_tx, c_ty, c_tz, parent_id, slot_count, features, units "
                                 "FROM keyframes WHERE map_id = ?1 ORDER BY id")),
        points_(db.prepare_statement(
            "SELECT id, x, y, z, nx, ny, nz, min_distance, max_distance, descriptor, "
            "reference_keyframe_id, visible, found FROM map_points WHERE map_id = ?1 ORDER BY id")),
        observations_(db.prepare_statement("SELECT o.keyframe_id, o.slot, o.map_point_id FROM observations o "
                                           "JOIN keyframes k ON k.id = o.keyframe_id WHERE k.map_id = ?1 "
                                           "ORDER BY o.keyframe_id, o.slot")),
        covisibility_(db.prepare_statement("SELECT c.keyframe_id, c.other_id, c.weight FROM covisibility c "
                                           "JOIN keyframes k ON k.id = c.keyframe_id WHERE k.map_id = ?1 "
                                           "ORDER BY c.keyframe_id, c.other_id")),
        loop_edges_(db.prepare_statement("SELECT l.keyframe_id, l.other_id FROM loop_edges l "
                                         "JOIN keyframes k ON k.id = l.keyframe_id WHERE k.map_id = ?1 "
                                         "ORDER BY l.keyframe_id, l.other_id")),
        culled_(db.prepare_statement("SELECT id, parent_id, qw, qx, qy, qz, tx, ty, tz, units FROM culled_keyframes "
                                     "WHERE map_id = ?1 ORDER BY id")),
        inertial_links_(
            db.prepare_statement("SELECT l.keyframe_id, l.previous_id, l.increments, l.c_i_qw, l.c_i_qx, l.c_i_qy, "
                                 "l.c_i_qz, l.c_i_tx, l.c_i_ty, l.c_i_tz FROM keyframe_inertial_links l "
                                 "JOIN keyframes k ON k.id = l.keyframe_id WHERE k.map_id = ?1 "
                                 "ORDER BY l.keyframe_id")),
        imu_states_(
            db.prepare_statement("SELECT s.keyframe_id, s.vx, s.vy, s.vz, s.bgx, s.bgy, s.bgz, s.bax, s.bay, s.baz "
                                 "FROM keyframe_imu_states s JOIN keyframes k ON k.id = s.keyframe_id "
                                 "WHERE k.map_id = ?1 ORDER BY s.keyframe_id")),
        inertial_state_(
            db.prepare_statement("SELECT initialized_at_ns, gx, gy, gz, bgx, bgy, bgz, bax, bay, baz, keyframes, "
                                 "span_s, refinements, sgx, sgy, sgz, sax, say, saz FROM map_inertial_states "
                                 "WHERE map_id = ?1")) {}

  // The largest keyframe and map point ids read so far.
  std::optional<KeyframeId> max_keyframe_id;
  std::optional<MapPointId> max_map_point_id;

  void read_map(Map& map) {
    keyframes_by_id_.clear();
    points_by_id_.clear();
    const std::int64_t map_id = sql_id(map.id());
    read_keyframes(map, map_id);
    read_culled_keyframes(map, map_id);
    read_points(map, map_id);
    read_observations(map_id);
    read_graph(map_id);
    read_inertial(map, map_id);
    ++report_.maps;
  }

 private:
  [[noreturn]] void fail(const std::string& message) const { throw DataError(database_ + ": " + message); }

  std::shared_ptr<KeyFrame> keyframe_in_map(KeyframeId id, const std::string& who) const {
    const auto it = keyframes_by_id_.find(id);
    if (it == keyframes_by_id_.end()) fail(who + " refers to keyframe " + std::to_string(id) + ", not in its map");
    return it->second.keyframe;
  }

  void read_keyframes(Map& map, std::int64_t map_id) {
    SqlStatement& row = *keyframes_;
    row.bind_int64(1, map_id);
    while (row.step()) {
      const KeyframeId id = id_column(row, 0);
      const std::string what = database_ + ": keyframe " + std::to_string(id);
      StoredFeatures stored = decode_features(row.blob(19), what);
      const std::int64_t slot_count = row.int64(18);
      if (slot_count < 0 || static_cast<std::uint64_t>(slot_count) != stored.features.keypoints.size())
        fail("keyframe " + std::to_string(id) + ": slot_count " + std::to_string(slot_count) + " but " +
             std::to_string(stored.features.keypoints.size()) + " keypoints in its features blob");
      KeyFrameData data;
      data.timestamp_ns = row.int64(2);
      data.T_w_b = pose_columns(row, 3);
      data.T_b_c = pose_columns(row, 10);
      data.features = std::move(stored.features);
      data.depth = std::move(stored.depth);
      data.u_right = std::move(stored.u_right);
      // Recomputed, not stored (docs/schema.md): the same words as tracking made,
      // since the vocabulary's hash matches the atlas's.
      if (vocabulary_ && !data.features.descriptors.empty())
        vocabulary_->transform(data.features.descriptors, &data.bow, &data.feature_vector);
      if (data.features.width > 0 && data.features.height > 0) data.grid = FeatureGrid(data.features);

      LoadedKeyframe loaded;
      if (!row.is_null(17)) loaded.parent = id_column(row, 17);
      if (!row.is_null(1)) report_.keyframe_sessions[id] = id_column(row, 1);
      loaded.keyframe = KeyFrame::create(id, map.id(), std::move(data), map.counters());
      const double units = row.real(20);
      if (!(std::isfinite(units) && units > 0.0))
        fail("keyframe " + std::to_string(id) + ": units " + std::to_string(units));
      loaded.keyframe->set_units(units);
      map.add_keyframe(loaded.keyframe);
      keyframes_by_id_.emplace(id, std::move(loaded));
      max_keyframe_id = std::max(max_keyframe_id.value_or(0), id);
      ++report_.keyframes;
    }
    row.reset();
  }

  // The anchors culled keyframes left for Map::keyframe_pose. Every chain of
  // parents must end at an alive keyframe of the map or at a root, without a
  // cycle: otherwise a frame anchored to it could not be resolved.
  void read_culled_keyframes(Map& map, std::int64_t map_id) {
    std::vector<Map::CulledKeyframe> culled;
    std::unordered_map<KeyframeId, std::optional<KeyframeId>> parent_of;
    culled_->bind_int64(1, map_id);
    while (culled_->step()) {
      Map::CulledKeyframe c;
      c.id = id_column(*culled_, 0);
      if (!culled_->is_null(1)) c.parent = id_column(*culled_, 1);
      c.T_parent_b = pose_columns(*culled_, 2);
      c.units = culled_->real(9);
      if (!(std::isfinite(c.units) && c.units > 0.0))
        fail("culled keyframe " + std::to_string(c.id) + ": units " + std::to_string(c.units));
      if (keyframes_by_id_.contains(c.id))
        fail("culled keyframe " + std::to_string(c.id) + " is also an alive keyframe of map " +
             std::to_string(map.id()));
      parent_of.emplace(c.id, c.parent);
      culled.push_back(c);
      max_keyframe_id = std::max(max_keyframe_id.value_or(0), c.id);
    }
    culled_->reset();
    std::unordered_map<KeyframeId, bool> resolves;  // memo: chains share their tails
    for (const Map::CulledKeyframe& c : culled) {
      std::vector<KeyframeId> chain = {c.id};
      std::optional<KeyframeId> next = c.parent;
      while (next && parent_of.contains(*next) && !resolves.contains(*next)) {
        if (chain.size() > parent_of.size())
          fail("culled keyframe " + std::to_string(c.id) + ": its chain of parents has a cycle");
        chain.push_back(*next);
        next = parent_of.at(*next);
      }
      const bool ok = !next || keyframes_by_id_.contains(*next) || resolves.contains(*next);
      if (!ok)
        fail("culled keyframe " + std::to_string(chain.back()) + ": parent " + std::to_string(*next) +
             " is neither a keyframe nor a culled keyframe of map " + std::to_string(map.id()));
      for (const KeyframeId id : chain) resolves[id] = true;
    }
    map.restore_culled_keyframes(culled);
    report_.culled_keyframes += culled.size();
  }

  void read_points(Map& map, std::int64_t map_id) {
    SqlStatement& row = *points_;
    row.bind_int64(1, map_id);
    while (row.step()) {
      const MapPointId id = id_column(row, 0);
      const std::string who = "map point " + std::to_string(id);
      MapPointData data;
      data.p_w = {row.real(1), row.real(2), row.real(3)};
      data.normal = {row.real(4), row.real(5), row.real(6)};
      data.min_distance = static_cast<float>(row.real(7));
      data.max_distance = static_cast<float>(row.real(8));
      data.descriptor = decode_descriptor(row.blob(9), database_ + ": " + who);
      auto mp = MapPoint::create(id, map.id(), data, map.counters());
      // The statistics start at 1 (ORB-SLAM's convention) and only count up.
      mp->increase_visible(static_cast<int>(row.int64(11)) - mp->visible());
      mp->increase_found(static_cast<int>(row.int64(12)) - mp->found());
      map.add_map_point(mp);
      references_[id] = row.is_null(10) ? std::nullopt : std::optional<KeyframeId>(id_column(row, 10));
      points_by_id_.emplace(id, std::move(mp));
      max_map_point_id = std::max(max_map_point_id.value_or(0), id);
      ++report_.map_points;
    }
    row.reset();
  }

  void read_observations(std::int64_t map_id) {
    SqlStatement& row = *observations_;
    row.bind_int64(1, map_id);
    while (row.step()) {
      const KeyframeId kf_id = id_column(row, 0);
      const std::int64_t slot = row.int64(1);
      const MapPointId mp_id = id_column(row, 2);
      const std::string who = "observation (keyframe " + std::to_string(kf_id) + ", slot " + std::to_string(slot) + ")";
      const auto kf = keyframe_in_map(kf_id, who);
      const auto mp = points_by_id_.find(mp_id);
      if (mp == points_by_id_.end()) fail(who + " refers to map point " + std::to_string(mp_id) + ", not in its map");
      if (slot < 0 || static_cast<std::uint64_t>(slot) >= kf->slot_count()) fail(who + ": slot out of range");
      kf->add_observation(static_cast<std::size_t>(slot), mp->second);
      ++report_.observations;
    }
    row.reset();
    // After the observations: attaching the first observer makes it the reference.
    for (const auto& [mp_id, ref] : references_) {
      const auto& mp = points_by_id_.at(mp_id);
      mp->set_reference_keyframe(ref ? keyframe_in_map(*ref, "map point " + std::to_string(mp_id)) : nullptr);
    }
    references_.clear();
  }

  void read_graph(std::int64_t map_id) {
    covisibility_->bind_int64(1, map_id);
    while (covisibility_->step()) {
      const KeyframeId a = id_column(*covisibility_, 0), b = id_column(*covisibility_, 1);
      const std::int64_t weight = covisibility_->int64(2);
      const std::string who = "covisibility link " + std::to_string(a) + " -> " + std::to_string(b);
      if (weight <= 0 || weight > std::numeric_limits<int>::max()) fail(who + ": weight " + std::to_string(weight));
      // Directed, as stored: the neighbour's own row restores its side.
      keyframe_in_map(a, who)->add_connection(keyframe_in_map(b, who), static_cast<int>(weight));
      ++report_.covisibility_links;
    }
    covisibility_->reset();

    for (const auto& [id, loaded] : keyframes_by_id_) {
      if (!loaded.parent) continue;
      loaded.keyframe->set_parent(keyframe_in_map(*loaded.parent, "keyframe " + std::to_string(id) + " (parent)"));
    }

    loop_edges_->bind_int64(1, map_id);
    while (loop_edges_->step()) {
      const KeyframeId a = id_column(*loop_edges_, 0), b = id_column(*loop_edges_, 1);
      const std::string who = "loop edge " + std::to_string(a) + " - " + std::to_string(b);
      keyframe_in_map(a, who)->add_loop_edge(keyframe_in_map(b, who));  // adds both directions
      ++report_.loop_edges;
    }
    loop_edges_->reset();
  }

  // The IMU in the camera of an inertial link (schema 8): none when all seven
  // columns are NULL (a link stored before), else a finite pose with a unit
  // quaternion.
  std::optional<Pose3> imu_in_camera(const SqlStatement& row, int first, const std::string& who) const {
    int nulls = 0;
    for (int c = first; c < first + 7; ++c) nulls += row.is_null(c) ? 1 : 0;
    if (nulls == 7) return std::nullopt;
    if (nulls != 0) fail(who + ": the IMU in the camera is stored in part (" + std::to_string(nulls) + " of 7 NULL)");
    const Pose3 T_c_i = pose_columns(row, first);
    if (!T_c_i.t.allFinite() || !T_c_i.q.coeffs().allFinite() || std::abs(T_c_i.q.norm() - 1.0) > 1e-6)
      fail(who + ": the IMU in the camera is not a finite pose with a unit quaternion");
    return T_c_i;
  }

  void read_inertial(Map& map, std::int64_t map_id) {
    inertial_links_->bind_int64(1, map_id);
    while (inertial_links_->step()) {
      const KeyframeId id = id_column(*inertial_links_, 0), previous = id_column(*inertial_links_, 1);
      const std::string who = "inertial link " + std::to_string(previous) + " -> " + std::to_string(id);
      auto increments =
          std::make_shared<const Preintegration>(decode_increments(inertial_links_->blob(2), database_ + ": " + who));
      keyframe_in_map(id, who)->set_inertial_link(keyframe_in_map(previous, who), std::move(increments),
                                                  imu_in_camera(*inertial_links_, 3, who));
      ++report_.inertial_links;
    }
    inertial_links_->reset();
    imu_states_->bind_int64(1, map_id);
    while (imu_states_->step()) {
      const KeyframeId id = id_column(*imu_states_, 0);
      const std::string who = "IMU state of keyframe " + std::to_string(id);
      KeyFrame::ImuState state;
      state.v_i = {imu_states_->real(1), imu_states_->real(2), imu_states_->real(3)};
      state.bias.gyro = {imu_states_->real(4), imu_states_->real(5), imu_states_->real(6)};
      state.bias.accel = {imu_states_->real(7), imu_states_->real(8), imu_states_->real(9)};
      if (!state.v_i.allFinite() || !state.bias.gyro.allFinite() || !state.bias.accel.allFinite())
        fail(who + " is not finite");
      keyframe_in_map(id, who)->set_imu_state(state);
      ++report_.imu_states;
    }
    imu_states_->reset();
    inertial_state_->bind_int64(1, map_id);
    if (inertial_state_->step()) {
      Map::InertialState state;
      state.initialized_at_ns = inertial_state_->int64(0);
      state.gravity_w = {inertial_state_->real(1), inertial_state_->real(2), inertial_state_->real(3)};
      state.bias.gyro = {inertial_state_->real(4), inertial_state_->real(5), inertial_state_->real(6)};
      state.bias.accel = {inertial_state_->real(7), inertial_state_->real(8), inertial_state_->real(9)};
      state.keyframes = static_cast<std::size_t>(inertial_state_->int64(10));
      state.span_s = inertial_state_->real(11);
      state.refinements = static_cast<std::size_t>(inertial_state_->int64(12));
      state.scale.gyro = {inertial_state_->real(13), inertial_state_->real(14), inertial_state_->real(15)};
      state.scale.accel = {inertial_state_->real(16), inertial_state_->real(17), inertial_state_->real(18)};
      if (!state.gravity_w.allFinite() || !state.bias.gyro.allFinite() || !state.bias.accel.allFinite() ||
          !state.scale.gyro.allFinite() || !state.scale.accel.allFinite())
        fail("map " + std::to_string(map.id()) + ": its inertial state is not finite");
      map.set_inertial_state(state);
    }
    inertial_state_->reset();
  }

  const std::string database_;
  const Vocabulary* const vocabulary_;  // not owned, may be null
  AtlasLoadReport& report_;
  using Statement = std::unique_ptr<SqlStatement>;
  Statement keyframes_, points_, observations_, covisibility_, loop_edges_, culled_, inertial_links_, imu_states_,
      inertial_state_;
  std::unordered_map<KeyframeId, LoadedKeyframe> keyframes_by_id_;  // of the current map
  std::unordered_map<MapPointId, std::shared_ptr<MapPoint>> points_by_id_;
  std::unordered_map<MapPointId, std::optional<KeyframeId>> references_;
};

}  // namespace

AtlasLoadReport AtlasStore::load_atlas(Atlas& atlas, const Vocabulary* vocabulary) {
  ORBATLAS_CHECK(atlas.maps().empty(), location() << ": load_atlas needs an atlas without maps");
  ORBATLAS_CHECK(
      !vocabulary || vocabulary->hash() == vocabulary_hash_,
      location() << ": loading with vocabulary " << vocabulary->hash() << " an atlas built with " << vocabulary_hash_);
  AtlasLoadReport report;
  SqlTransaction transaction(*db_, SqlTransaction::Mode::kRead);
  const std::unique_ptr<SqlStatement> meta = db_->prepare_statement(
      "SELECT next_keyframe_id, next_map_point_id, next_map_id, active_map_id FROM atlas WHERE id = 1");
  ORBATLAS_DATA_CHECK(meta->step(), location() << ": the atlas row is missing");
  const std::uint64_t next_keyframe = id_column(*meta, 0), next_point = id_column(*meta, 1),
                      next_map = id_column(*meta, 2);
  // A flag and a value rather than std::optional: GCC 12 warns (falsely) about the latter here.
  const bool has_active = !meta->is_null(3);
  const MapId active = has_active ? id_column(*meta, 3) : 0;
  meta->reset();

  {
    AtlasReader reader(*db_, vocabulary, report);
    for (const MapId id : stored_map_ids()) reader.read_map(*atlas.add_map(id));
    // Above every loaded id, and above what the saved atlas had handed out: ids
    // of culled objects (still named by trajectories) are never reused.
    IdAllocator& ids = atlas.ids();
    if (reader.max_keyframe_id) ids.ensure_above(IdKind::keyframe, *reader.max_keyframe_id);
    if (reader.max_map_point_id) ids.ensure_above(IdKind::map_point, *reader.max_map_point_id);
    if (next_keyframe > 0) ids.ensure_above(IdKind::keyframe, next_keyframe - 1);
    if (next_point > 0) ids.ensure_above(IdKind::map_point, next_point - 1);
    if (next_map > 0) ids.ensure_above(IdKind::map, next_map - 1);  // add_map covered the loaded ones
  }
  if (has_active) atlas.set_active(active);
  transaction.commit();
  return report;
}

std::shared_ptr<Map> AtlasStore::load_map(const Atlas& atlas, MapId id, const Vocabulary* vocabulary) {
  ORBATLAS_CHECK(
      !vocabulary || vocabulary->hash() == vocabulary_hash_,
      location() << ": loading with vocabulary " << vocabulary->hash() << " an atlas built with " << vocabulary_hash_);
  AtlasLoadReport report;
  SqlTransaction transaction(*db_, SqlTransaction::Mode::kRead);
  const auto stored = stored_map_ids();
  if (std::find(stored.begin(), stored.end(), id) == stored.end()) return nullptr;
  std::shared_ptr<Map> map = atlas.detached_map(id);
  {
    AtlasReader reader(*db_, vocabulary, report);
    reader.read_map(*map);
  }
  transaction.commit();
  return map;
}

}  // namespace orbatlas
