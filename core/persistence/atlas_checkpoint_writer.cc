#include "core/persistence/atlas_checkpoint_writer.h"

#include <algorithm>

#include "core/common/error.h"
#include "core/persistence/row_hash.h"
#include "core/persistence/session_rows.h"
#include "core/persistence/wall_clock.h"

namespace orbatlas {

AtlasCheckpointWriter::AtlasCheckpointWriter(const Atlas& atlas, AtlasStore store,
                                             std::optional<CheckpointSession> session)
    : atlas_(atlas),
      store_(std::move(store)),
      session_(std::move(session)),
      // Ids only grow: every keyframe made from now on is the session's.
      first_session_keyframe_(atlas.ids().peek(IdKind::keyframe)) {}

void AtlasCheckpointWriter::set_durable(bool durable) {
  store_.db_.exec(durable ? "PRAGMA synchronous = FULL" : "PRAGMA synchronous = NORMAL");
}

std::vector<AtlasCheckpointWriter::TrajectoryRow> AtlasCheckpointWriter::current_trajectory() const {
  std::vector<TrajectoryRow> rows;
  if (!session_ || !session_->trajectory) return rows;
  for (const FrameAnchor& a : session_->trajectory())
    rows.push_back({a, RowHash().add(a.map).add(a.reference).add(a.T_ref_b).value()});
  std::sort(rows.begin(), rows.end(), [](const auto& a, const auto& b) { return a.anchor.t_ns < b.anchor.t_ns; });
  const auto same_time = [](const auto& a, const auto& b) { return a.anchor.t_ns == b.anchor.t_ns; };
  const auto repeated = std::adjacent_find(rows.begin(), rows.end(), same_time);
  ORBATLAS_CHECK(repeated == rows.end(), store_.path().string() << ": session " << session_->info.id
                                                                << ": two frames at timestamp " << repeated->anchor.t_ns);
  return rows;
}

RowCounts AtlasCheckpointWriter::write_trajectory(AtlasRowWriter& writer, const std::vector<TrajectoryRow>& before,
                                                  const std::vector<TrajectoryRow>& now) const {
  RowCounts counts;
  if (!session_) return counts;
  const SessionId id = session_->info.id;
  auto a = before.begin(), b = now.begin();
  while (a != before.end() || b != now.end()) {
    if (b == now.end() || (a != before.end() && a->anchor.t_ns < b->anchor.t_ns)) {
      writer.delete_trajectory(id, a->anchor.t_ns);
      ++counts.deleted;
      ++a;
    } else if (a == before.end() || b->anchor.t_ns < a->anchor.t_ns) {
      writer.upsert_trajectory(id, b->anchor);
      ++counts.inserted;
      ++b;
    } else {
      if (a->hash != b->hash) {
        writer.upsert_trajectory(id, b->anchor);
        ++counts.updated;
      }
      ++a;
      ++b;
    }
  }
  return counts;
}

CheckpointResult AtlasCheckpointWriter::checkpoint(const std::function<void()>& before_transaction) {
  SqliteDb& db = store_.db_;
  const TimestampNs now = unix_time_ns();
  const bool full = !has_committed_;
  if (full) stored_sessions_ = AtlasRowWriter(db).stored_keyframe_sessions();

  // The snapshot is taken before the write lock, which is then held only for writing.
  const SessionId session_id = session_ ? session_->info.id : 0;
  AtlasRows rows = collect_atlas_rows(atlas_, [&](KeyframeId id) -> std::optional<SessionId> {
    if (session_ && id >= first_session_keyframe_) return session_id;
    if (const auto it = stored_sessions_.find(id); it != stored_sessions_.end()) return it->second;
    return std::nullopt;
  });
  std::vector<TrajectoryRow> trajectory = current_trajectory();

  const AtlasRows nothing;
  const std::vector<TrajectoryRow> no_frames;
  const AtlasRows& before = full ? nothing : committed_;
  CheckpointResult result;
  result.full = full;
  if (before_transaction) before_transaction();
  SqliteTransaction transaction(db);
  {
    AtlasRowWriter writer(db);  // its statements are finalized before COMMIT
    if (full) {
      if (session_) {
        write_session_rows(db, session_->info);
        writer.delete_session_trajectory(session_id);
        ++result.rows.inserted;
      }
      for (const MapId map : rows.maps) writer.delete_map_contents(map);
    }
    result.rows += write_changed_rows(writer, before, rows, now);
    result.rows += write_trajectory(writer, full ? no_frames : committed_trajectory_, trajectory);
    if (meta_changed(before, rows)) ++result.rows.updated;
    if (result.rows.total() == 0) return result;  // rolls back an empty transaction: nothing touched the file
    result.sequence = writer.write_meta(*rows.meta, now);
  }
  transaction.commit();
  // Only now: a failure anywhere above leaves the cache describing the file.
  result.committed = true;
  rows.drop_objects();
  committed_ = std::move(rows);
  committed_trajectory_ = std::move(trajectory);
  has_committed_ = true;
  return result;
}

}  // namespace orbatlas
