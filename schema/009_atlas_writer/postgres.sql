-- orbatlas persistent atlas in PostgreSQL, schema version 2 (issue 23,
-- docs/schema.md "Crash safety"): the PostgreSQL form of SQLite's lock file
-- "<db>.lock". The one writer of the atlas holds a session-level advisory lock
-- on its connection (core/persistence/pg_writer_lock.h), which goes when that
-- connection dies; this row says whether the last writer stopped cleanly
-- ('stopped', after its final checkpoint) or died ('running' left behind), so
-- that the next one moves the id counters past what the dead one handed out.
-- PostgreSQL only: SQLite keeps the same record in the lock file.

CREATE TABLE atlas_writer (
  id         bigint PRIMARY KEY CHECK (id = 1),
  state      text   NOT NULL CHECK (state IN ('running', 'stopped')),
  holder     text   NOT NULL,  -- "pid N on host H", for the message a second writer gets
  changed_ns bigint NOT NULL
);
