-- orbatlas persistent atlas, schema version 3 (docs/schema.md): upload jobs, so
-- that a job id is never handed out twice across restarts and a job the server
-- was running when it died is reported (as failed, interrupted) after a restart.
-- Applied in one transaction by the migration runner.
CREATE TABLE upload_jobs (
  id            INTEGER PRIMARY KEY CHECK (id >= 1),
  name          TEXT    NOT NULL,
  state         TEXT    NOT NULL CHECK (state IN ('queued', 'extracting', 'running', 'done', 'failed', 'cancelled')),
  -- The session the job streams into (stored at its creation); kept when the
  -- session row goes.
  session_id    INTEGER REFERENCES sessions(id) ON DELETE SET NULL,
  created_ns    INTEGER NOT NULL,
  archive_bytes INTEGER NOT NULL DEFAULT 0 CHECK (archive_bytes >= 0),
  frames_total  INTEGER NOT NULL DEFAULT 0 CHECK (frames_total >= 0),
  frames_done   INTEGER NOT NULL DEFAULT 0 CHECK (frames_done >= 0),
  tracked       INTEGER NOT NULL DEFAULT 0 CHECK (tracked >= 0),
  rejected      INTEGER NOT NULL DEFAULT 0 CHECK (rejected >= 0),
  ate_rmse_m    REAL,
  error         TEXT    NOT NULL DEFAULT ''
) STRICT;

PRAGMA user_version = 3;
