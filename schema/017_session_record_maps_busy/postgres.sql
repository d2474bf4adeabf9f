-- orbatlas persistent atlas in PostgreSQL, schema version 17 (sqlite.sql beside
-- this file, docs/schema.md): a session's record keeps its maps_busy frames.
ALTER TABLE session_records ADD COLUMN maps_busy_frames bigint NOT NULL DEFAULT 0 CHECK (maps_busy_frames >= 0);
