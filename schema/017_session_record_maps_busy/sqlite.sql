-- orbatlas persistent atlas, schema version 17 (docs/schema.md): a session's
-- record keeps its frames answered untracked because the maps were held past
-- the session's bound (`maps_busy_frames`), as it keeps its skipped ones; a
-- record written before this has 0.
ALTER TABLE session_records ADD COLUMN maps_busy_frames INTEGER NOT NULL DEFAULT 0 CHECK (maps_busy_frames >= 0);

PRAGMA user_version = 17;
