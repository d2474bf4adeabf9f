-- orbatlas persistent atlas in PostgreSQL, schema version 4 (issue 23,
-- docs/scaling.md "Replicas"): which replica writes which map. A replica
-- writes (maps, checkpoints) only the maps it owns here; every replica reads
-- every map. A map made by a replica is claimed by its first checkpoint; the
-- maps of a replica whose lease has passed are taken over by another one,
-- which reads them again from here before it writes them. A checkpoint locks
-- its replica's rows (FOR SHARE) in its transaction, so a takeover waits for a
-- checkpoint in progress and the old owner writes nothing after it. `version`
-- grows with each checkpoint that changed the map's rows: the other replicas
-- read a map again when its version is not the one they have.
-- PostgreSQL only: an SQLite atlas has one writer.

CREATE TABLE map_owners (
  map_id     bigint PRIMARY KEY,
  replica_id bigint NOT NULL REFERENCES replicas(id) ON DELETE CASCADE,
  claimed_ns bigint NOT NULL,
  version    bigint NOT NULL DEFAULT 0
);
CREATE INDEX map_owners_by_replica ON map_owners(replica_id);
