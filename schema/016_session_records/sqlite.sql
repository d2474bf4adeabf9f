-- orbatlas persistent atlas, schema version 16 (docs/schema.md): what each
-- session did, as its last checkpoint stored it, so that a session read back by
-- a later run reports the frames, keyframes and end it had, not what its stored
-- trajectory implies. Written by the checkpoint that writes its frames, in the
-- same transaction; a session stored before schema 9 has no row.
CREATE TABLE session_records (
  session_id      INTEGER PRIMARY KEY REFERENCES sessions(id) ON DELETE CASCADE,
  frames          INTEGER NOT NULL CHECK (frames >= 0),
  tracked         INTEGER NOT NULL CHECK (tracked >= 0 AND tracked <= frames),
  keyframes       INTEGER NOT NULL CHECK (keyframes >= 0),
  rejected_frames INTEGER NOT NULL CHECK (rejected_frames >= 0),
  skipped_frames  INTEGER NOT NULL CHECK (skipped_frames >= 0),
  imu_samples     INTEGER NOT NULL CHECK (imu_samples >= 0),
  mode            TEXT    NOT NULL CHECK (mode IN ('', 'map', 'localize')),
  config          TEXT    NOT NULL,
  -- 'active': the last checkpoint saw it running (the server stopped before its end was stored)
  outcome         TEXT    NOT NULL CHECK (outcome IN ('active', 'finished', 'failed')),
  ended_by        TEXT    NOT NULL,
  error           TEXT    NOT NULL
) STRICT;

PRAGMA user_version = 16;
