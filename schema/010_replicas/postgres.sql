-- orbatlas persistent atlas in PostgreSQL, schema version 3 (issue 23,
-- docs/scaling.md "Replicas"): the orbatlas-server replicas that use this
-- database. A replica adds its row when it starts and renews its lease while
-- it runs (core/server/replica_registry.h); a replica whose lease has passed is
-- dead (SIGKILL, a crash, a lost network), whatever its state says. Leases are
-- in the database's clock (now()), so the replicas' own clocks never have to
-- agree. Rows of replicas gone for a day are deleted by the next one to start.
-- PostgreSQL only: an SQLite atlas has one server, which is its only replica.

CREATE TABLE replicas (
  id          bigserial   PRIMARY KEY,
  holder      text        NOT NULL,  -- "pid N on host H"
  url         text        NOT NULL,  -- its HTTP API ('' when it did not say)
  started_ns  bigint      NOT NULL,  -- Unix time, nanoseconds (the replica's clock)
  lease_until timestamptz NOT NULL,  -- the database's clock
  state       text        NOT NULL CHECK (state IN ('running', 'stopped'))
);
