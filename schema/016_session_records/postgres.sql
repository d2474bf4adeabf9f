-- orbatlas persistent atlas in PostgreSQL, schema version 16 (sqlite.sql beside
-- this file, docs/schema.md): what each session did, as its last checkpoint stored it.
CREATE TABLE session_records (
  session_id      bigint PRIMARY KEY REFERENCES sessions(id) ON DELETE CASCADE,
  frames          bigint NOT NULL CHECK (frames >= 0),
  tracked         bigint NOT NULL CHECK (tracked >= 0 AND tracked <= frames),
  keyframes       bigint NOT NULL CHECK (keyframes >= 0),
  rejected_frames bigint NOT NULL CHECK (rejected_frames >= 0),
  skipped_frames  bigint NOT NULL CHECK (skipped_frames >= 0),
  imu_samples     bigint NOT NULL CHECK (imu_samples >= 0),
  mode            text   NOT NULL CHECK (mode IN ('', 'map', 'localize')),
  config          text   NOT NULL,
  outcome         text   NOT NULL CHECK (outcome IN ('active', 'finished', 'failed')),
  ended_by        text   NOT NULL,
  error           text   NOT NULL
);
