-- orbatlas persistent atlas in PostgreSQL, schema version 8 (issue 23,
-- docs/scaling.md "Replicas"): the merge work of mapping sessions still live.
-- A replica adds a session's row when the session starts; when the session
-- finishes, the replica leaves the merge work of its maps in shared_merges and
-- deletes the row. When the replica dies (or stops) first, any other replica
-- turns the row into shared_merges rows for the maps the session's stored
-- keyframes are in, so the search, merge and global BA that the session's end
-- would have started are done by whichever replica writes those maps (a
-- global BA the dead replica's live mapping lost is done again so).
-- PostgreSQL only: an SQLite atlas has one server.

CREATE TABLE shared_session_work (
  session_id bigint PRIMARY KEY REFERENCES sessions(id) ON DELETE CASCADE,
  replica_id bigint NOT NULL,
  request    text   NOT NULL,  -- JSON, as shared_merges.request (core/server/shared_merges.h)
  started_ns bigint NOT NULL
);
CREATE INDEX shared_session_work_replica ON shared_session_work(replica_id);
