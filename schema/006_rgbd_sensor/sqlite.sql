-- orbatlas persistent atlas, schema version 6 (docs/schema.md): the rgbd
-- sensor (an image and its registered depth image; docs/monocular.md, issue
-- 20) among the sensors a session may have. SQLite cannot change a CHECK
-- constraint, so `sessions` is rebuilt as SQLite documents it: a new table,
-- the rows copied, the old one dropped and the new one renamed (the runner
-- turns foreign keys off for the migration, so the drop does not cascade into
-- cameras, keyframes or trajectories, and checks them before committing).

CREATE TABLE sessions_v6 (
  id         INTEGER PRIMARY KEY CHECK (id >= 0),
  name       TEXT    NOT NULL,
  sensor     TEXT    NOT NULL CHECK (sensor IN ('mono', 'stereo', 'mono_inertial', 'stereo_inertial', 'rgbd')),
  created_ns INTEGER NOT NULL
) STRICT;

INSERT INTO sessions_v6(id, name, sensor, created_ns) SELECT id, name, sensor, created_ns FROM sessions;
DROP TABLE sessions;
ALTER TABLE sessions_v6 RENAME TO sessions;

PRAGMA user_version = 6;
