#include "core/persistence/atlas_checkpoint_writer.h"

#include <algorithm>
#include <unordered_set>

#include "core/common/error.h"
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
  SqlConnection& db = *store_.db_;
  if (db.dialect() == SqlDialect::kSqlite) {
    db.exec(durable ? "PRAGMA synchronous = FULL" : "PRAGMA synchronous = NORMAL");
  } else {
    // The same trade on PostgreSQL: off, a commit returns before its WAL
    // record is flushed (a server crash may lose the last ones, never consistency).
    db.exec(durable ? "SET synchronous_commit = on" : "SET synchronous_commit = off");
  }
}

void AtlasCheckpointWriter::add_session(CheckpointSession session) {
  for (const SessionState& s : sessions_)
    ORBATLAS_CHECK(s.session.info.id != session.info.id,
                   store_.location() << ": session " << session.info.id << " is already checkpointed");
  SessionState state;
  state.session = std::move(session);
  sessions_.push_back(std::move(state));
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

AtlasCheckpointWriter::NewFrames AtlasCheckpointWriter::new_frames(const SessionState& state) const {
  NewFrames out;
  out.frames = state.deferred;
  out.taken = state.taken;
  if (!state.session.trajectory) return out;
  std::optional<TimestampNs> last = state.last_t;
  for (const FrameAnchor& a : state.session.trajectory(state.taken)) {
    ORBATLAS_CHECK(!last || a.t_ns > *last, store_.location()
                                                << ": session " << state.session.info.id
                                                << (last && a.t_ns == *last ? ": two frames at timestamp "
                                                                            : ": a frame out of time order at ")
                                                << a.t_ns);
    last = a.t_ns;
    out.frames.push_back({a, 0});
    ++out.taken;
  }
  out.last_t = last;
  return out;
}

std::vector<FrameAnchor> AtlasCheckpointWriter::take_storable(std::vector<PendingFrame>& pending,
                                                              const std::unordered_set<KeyframeId>& stored_keyframes) {
  std::vector<FrameAnchor> storable;
  std::vector<PendingFrame> again;
  for (PendingFrame& f : pending) {
    if (stored_keyframes.count(f.anchor.reference)) {
      storable.push_back(f.anchor);
      continue;
    }
    ++deferred_frames_;
    if (++f.tries < kDeferrals)
      again.push_back(f);
    else
      ++dropped_frames_;
  }
  pending = std::move(again);
  return storable;
}

CheckpointResult AtlasCheckpointWriter::checkpoint(const std::function<void()>& before_transaction) {
  SqlConnection& db = *store_.db_;
  const TimestampNs now = unix_time_ns();
  const bool full = !has_committed_;
  if (full) stored_sessions_ = AtlasRowWriter(db).stored_keyframe_sessions();

  // The snapshot is taken before the write lock, which is then held only for
  // writing. The trajectories first: every keyframe their frames reference
  // existed before the atlas rows were collected, so it is in them (or among
  // their culled keyframes) unless a merge or a reset removed it meanwhile.
  std::vector<NewFrames> frames;
  for (const SessionState& s : sessions_) frames.push_back(new_frames(s));
  // The records after the frames: a record counts at least the frames stored with it.
  std::vector<std::optional<SessionRecord>> records;
  for (const SessionState& s : sessions_)
    records.push_back(s.session.record ? std::optional<SessionRecord>(s.session.record()) : std::nullopt);
  AtlasRows rows = collect_atlas_rows(atlas_, [&](KeyframeId id) { return session_of(id); });
  // Never a stored frame whose keyframe is not stored: it would resolve through
  // whatever keyframe later gets that id. Such a frame waits for the next
  // checkpoint (a few times at most).
  std::unordered_set<KeyframeId> stored_keyframes;
  for (const KeyframeRow& k : rows.keyframes) stored_keyframes.insert(k.id);
  for (const CulledKeyframeRow& c : rows.culled) stored_keyframes.insert(c.anchor.id);
  if (!full)
    for (const CulledKeyframeRow& c : committed_.culled) stored_keyframes.insert(c.anchor.id);
  std::vector<std::vector<FrameAnchor>> storable;
  for (NewFrames& f : frames) storable.push_back(take_storable(f.frames, stored_keyframes));
  // What the sessions have taken, once it is in the file (or nothing was written).
  const auto advance_sessions = [&] {
    for (std::size_t i = 0; i < sessions_.size(); ++i) {
      sessions_[i].taken = frames[i].taken;
      sessions_[i].last_t = frames[i].last_t;
      sessions_[i].deferred = std::move(frames[i].frames);
    }
  };

  CheckpointResult result;
  result.full = full;
  if (before_transaction) before_transaction();
  SqlTransaction transaction(db);
  // The maps this writer writes now: every one, or (several writers) those it
  // may write inside this transaction. A map written for the first time, or
  // again after a time it could not be, is rewritten whole.
  // The removed maps as the snapshot saw them: a map merged away after it is
  // still in rows.maps (written as it was), and goes with the next checkpoint.
  const std::vector<MapId> removed = rows.removed_maps;
  std::vector<MapId> candidates = rows.maps;
  std::unordered_set<MapId> gone;
  for (const MapId map : removed)
    if (!deleted_maps_.count(map)) {
      candidates.push_back(map);
      if (std::find(rows.maps.begin(), rows.maps.end(), map) == rows.maps.end()) gone.insert(map);
    }
  const std::unordered_set<MapId> writable = writable_maps_
                                                 ? writable_maps_(db, candidates, gone)
                                                 : std::unordered_set<MapId>(candidates.begin(), candidates.end());
  const bool every_map = writable.size() == candidates.size();
  const auto is_writable = [&](MapId m) { return writable.count(m) > 0; };
  const auto written_before = [&](MapId m) { return !full && written_maps_.count(m) > 0; };
  if (!every_map) rows = rows_of_maps(std::move(rows), is_writable);
  const AtlasRows nothing;
  const bool before_is_committed =
      !full && std::all_of(rows.maps.begin(), rows.maps.end(), written_before) &&
      std::all_of(written_maps_.begin(), written_maps_.end(), [&](MapId m) { return writable.count(m) > 0; });
  // What the file holds of the maps written now (rows of maps rewritten whole are deleted first).
  const AtlasRows restricted = full || before_is_committed ? AtlasRows{} : rows_of_maps(committed_, [&](MapId m) {
    return is_writable(m) && written_before(m);
  });
  const AtlasRows& before = full ? nothing : before_is_committed ? committed_ : restricted;
  std::unordered_map<MapId, std::uint64_t> digests;  // of `rows`, with maps_changed_
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
      for (const FrameAnchor& a : storable[i]) writer.upsert_trajectory(s.session.info.id, a);
      result.rows.inserted += storable[i].size();
      if (records[i] && (rewrite || s.written_record != records[i])) {
        write_session_record(db, s.session.info.id, *records[i]);
        ++result.rows.updated;
      }
    }
    // Maps merged into others since loading go (unless their rows are in
    // `before`: then the diff deletes them); other stored maps stay.
    for (const MapId map : removed)
      if (is_writable(map) && !deleted_maps_.count(map) && !written_before(map)) writer.delete_map(map);
    for (const MapId map : rows.maps)
      if (!written_before(map)) writer.delete_map_contents(map);
    result.rows += write_changed_rows(writer, before, rows, now);
    if (maps_changed_) {
      digests = map_digests(rows);
      std::vector<MapId> changed;
      for (const MapId map : rows.maps) {
        const auto it = committed_digests_.find(map);
        if (it == committed_digests_.end() || it->second != digests.at(map)) changed.push_back(map);
      }
      if (!changed.empty()) maps_changed_(db, changed);
    }
    if (meta_changed(before, rows)) ++result.rows.updated;
    if (result.rows.total() == 0) {
      // A map this writer may not write now is rewritten whole when it may again.
      if (!every_map) {
        std::erase_if(written_maps_, [&](MapId m) { return !is_writable(m); });
        committed_ = rows_of_maps(std::move(committed_), [&](MapId m) { return written_maps_.count(m) > 0; });
      }
      advance_sessions();  // their new frames, if any, were all deferred
      std::erase_if(sessions_, [](const SessionState& s) { return s.ending; });  // nothing left to write for them
      return result;  // rolls back an empty transaction: nothing touched the file
    }
    result.sequence = writer.write_meta(*rows.meta, now);
  }
  transaction.commit();
  // Only now: a failure anywhere above leaves the cache describing the file.
  result.committed = true;
  rows.drop_objects();
  written_maps_ = std::unordered_set<MapId>(rows.maps.begin(), rows.maps.end());
  for (const MapId map : removed)
    if (is_writable(map)) deleted_maps_.insert(map);
  committed_ = std::move(rows);
  if (maps_changed_) committed_digests_ = std::move(digests);
  for (std::size_t i = 0; i < sessions_.size(); ++i) {
    sessions_[i].written = true;
    if (records[i]) sessions_[i].written_record = records[i];
  }
  advance_sessions();
  std::erase_if(sessions_, [](const SessionState& s) { return s.ending; });
  has_committed_ = true;
  return result;
}

}  // namespace orbatlas
