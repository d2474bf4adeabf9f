#include "core/persistence/atlas_checkpoint_writer.h"

#include <algorithm>
#include <unordered_set>

#include "core/common/error.h"
#include "core/persistence/row_hash.h"
#include "core/persistence/session_rows.h"
#include "core/persistence/wall_clock.h"

namespace orbatlas {

AtlasCheckpointWriter::AtlasCheckpointWriter(const Atlas& atlas, AtlasStore store,
                                             std::optional<CheckpointSession> session)
    : atlas_(atlas),
      store_(std::move(store)),
      // Ids only grow: every keyframe made from now on is the session's.
      first_session_keyframe_(atlas.ids().peek(IdKind::keyframe)) {
  if (session) {
    claims_new_keyframes_ = session->info.id;
    add_session(std::move(*session));
  }
}

void AtlasCheckpointWriter::set_durable(bool durable) {
  store_.db_.exec(durable ? "PRAGMA synchronous = FULL" : "PRAGMA synchronous = NORMAL");
}

void AtlasCheckpointWriter::add_session(CheckpointSession session) {
  for (const SessionState& s : sessions_)
    ORBATLAS_CHECK(s.session.info.id != session.info.id,
                   store_.path().string() << ": session " << session.info.id << " is already checkpointed");
  sessions_.push_back({std::move(session), false, false, {}});
}

void AtlasCheckpointWriter::end_session(SessionId id) {
  for (SessionState& s : sessions_)
    if (s.session.info.id == id) s.ending = true;
}

void AtlasCheckpointWriter::attribute_keyframe(KeyframeId keyframe, SessionId session) {
  keyframe_sessions_[keyframe] = session;
}

std::optional<SessionId> AtlasCheckpointWriter::session_of(KeyframeId id) const {
  if (const auto it = keyframe_sessions_.find(id); it != keyframe_sessions_.end()) return it->second;
  if (claims_new_keyframes_ && id >= first_session_keyframe_) return *claims_new_keyframes_;
  if (const auto it = stored_sessions_.find(id); it != stored_sessions_.end()) return it->second;
  return std::nullopt;
}

std::vector<AtlasCheckpointWriter::TrajectoryRow> AtlasCheckpointWriter::current_trajectory(
    const CheckpointSession& session) const {
  std::vector<TrajectoryRow> rows;
  if (!session.trajectory) return rows;
  for (const FrameAnchor& a : session.trajectory())
    rows.push_back({a, RowHash().add(a.map).add(a.reference).add(a.T_ref_b).value()});
  std::sort(rows.begin(), rows.end(), [](const auto& a, const auto& b) { return a.anchor.t_ns < b.anchor.t_ns; });
  const auto same_time = [](const auto& a, const auto& b) { return a.anchor.t_ns == b.anchor.t_ns; };
  const auto repeated = std::adjacent_find(rows.begin(), rows.end(), same_time);
  ORBATLAS_CHECK(repeated == rows.end(), store_.path().string()
                                             << ": session " << session.info.id << ": two frames at timestamp "
                                             << repeated->anchor.t_ns);
  return rows;
}

void AtlasCheckpointWriter::keep_stored_references(std::vector<TrajectoryRow>& rows,
                                                   const std::vector<TrajectoryRow>& committed,
                                                   const std::unordered_set<KeyframeId>& stored_keyframes) {
  std::vector<TrajectoryRow> kept;
  kept.reserve(rows.size());
  for (TrajectoryRow& row : rows) {
    if (stored_keyframes.count(row.anchor.reference)) {
      kept.push_back(std::move(row));
      continue;
    }
    const auto before = std::lower_bound(committed.begin(), committed.end(), row.anchor.t_ns,
                                         [](const TrajectoryRow& r, TimestampNs t) { return r.anchor.t_ns < t; });
    if (before != committed.end() && before->anchor.t_ns == row.anchor.t_ns) kept.push_back(*before);
    ++deferred_frames_;
  }
  rows = std::move(kept);
}

RowCounts AtlasCheckpointWriter::write_trajectory(AtlasRowWriter& writer, SessionId id,
                                                  const std::vector<TrajectoryRow>& before,
                                                  const std::vector<TrajectoryRow>& now) {
  RowCounts counts;
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

  // The snapshot is taken before the write lock, which is then held only for
  // writing. The trajectories first: every keyframe their frames reference
  // existed before the atlas rows were collected, so it is in them (or among
  // their culled keyframes) unless a merge or a reset removed it meanwhile.
  std::vector<std::vector<TrajectoryRow>> trajectories;
  for (const SessionState& s : sessions_) trajectories.push_back(current_trajectory(s.session));
  AtlasRows rows = collect_atlas_rows(atlas_, [&](KeyframeId id) { return session_of(id); });
  // Never a stored frame whose keyframe is not stored: it would resolve through
  // whatever keyframe later gets that id. Such a frame keeps its committed row
  // (or waits for the next checkpoint).
  std::unordered_set<KeyframeId> stored_keyframes;
  for (const KeyframeRow& k : rows.keyframes) stored_keyframes.insert(k.id);
  for (const CulledKeyframeRow& c : rows.culled) stored_keyframes.insert(c.anchor.id);
  if (!full)
    for (const CulledKeyframeRow& c : committed_.culled) stored_keyframes.insert(c.anchor.id);
  for (std::size_t i = 0; i < sessions_.size(); ++i)
    keep_stored_references(trajectories[i], full ? std::vector<TrajectoryRow>{} : sessions_[i].committed,
                           stored_keyframes);

  const AtlasRows nothing;
  const std::vector<TrajectoryRow> no_frames;
  const AtlasRows& before = full ? nothing : committed_;
  CheckpointResult result;
  result.full = full;
  if (before_transaction) before_transaction();
  SqliteTransaction transaction(db);
  {
    AtlasRowWriter writer(db);  // its statements are finalized before COMMIT
    for (std::size_t i = 0; i < sessions_.size(); ++i) {
      const SessionState& s = sessions_[i];
      const bool rewrite = full || !s.written;
      if (rewrite) {
        write_session_rows(db, s.session.info);
        writer.delete_session_trajectory(s.session.info.id);
        ++result.rows.inserted;
      }
      result.rows += write_trajectory(writer, s.session.info.id, rewrite ? no_frames : s.committed, trajectories[i]);
    }
    if (full) {
      // Maps merged into others since loading go; other stored maps stay.
      for (const MapId map : atlas_.removed_maps()) writer.delete_map(map);
      for (const MapId map : rows.maps) writer.delete_map_contents(map);
    }
    result.rows += write_changed_rows(writer, before, rows, now);
    if (meta_changed(before, rows)) ++result.rows.updated;
    if (result.rows.total() == 0) {
      std::erase_if(sessions_, [](const SessionState& s) { return s.ending; });  // nothing left to write for them
      return result;  // rolls back an empty transaction: nothing touched the file
    }
    result.sequence = writer.write_meta(*rows.meta, now);
  }
  transaction.commit();
  // Only now: a failure anywhere above leaves the cache describing the file.
  result.committed = true;
  rows.drop_objects();
  committed_ = std::move(rows);
  for (std::size_t i = 0; i < sessions_.size(); ++i) {
    sessions_[i].written = true;
    sessions_[i].committed = std::move(trajectories[i]);
  }
  std::erase_if(sessions_, [](const SessionState& s) { return s.ending; });
  has_committed_ = true;
  return result;
}

}  // namespace orbatlas
