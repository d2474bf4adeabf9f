-- orbatlas persistent atlas in PostgreSQL, schema version 6 (issue 23,
-- docs/scaling.md "Replicas"): the merge work a finished session leaves (its
-- map searched for a place shared with the atlas's other maps, merged, refined
-- by a global BA). The replica that owns the map does it and then deletes the
-- row; when that replica dies first, the replica that takes its maps over
-- takes their merge work too. A replica started with --no-merging leaves its
-- rows to one that merges.
-- PostgreSQL only: an SQLite atlas has one server.

CREATE TABLE shared_merges (
  map_id       bigint PRIMARY KEY,
  request      text   NOT NULL,  -- JSON: the session's settings, first keyframe, IMU (core/server/shared_merges.h)
  requested_ns bigint NOT NULL
);
