-- orbatlas persistent atlas in PostgreSQL, schema version 7 (issue 23,
-- docs/scaling.md "Replicas"): merge work claimed row by row, and idle maps
-- handed from one live replica to another.
-- - shared_merges.claimed_by: the replica whose merging worker has the row
--   (claimed FOR UPDATE SKIP LOCKED by the map's owner); NULL: waiting. A row
--   claimed by a replica that stopped or died waits again.
-- - shared_merges.retry_ns: a row put back (its place was found in a map
--   another replica writes) is not claimed again before this time.
-- - map_owners.wanted_by: a replica that has merge work for this map (its own
--   row waited a lease unclaimed, or the map is the place its merge found)
--   asks the owner for it; the owner hands the map over (checkpoint first,
--   then replica_id = wanted_by) once no session and no merge of its own
--   works in it.
-- PostgreSQL only: an SQLite atlas has one server.

ALTER TABLE shared_merges ADD COLUMN claimed_by bigint;
ALTER TABLE shared_merges ADD COLUMN retry_ns bigint NOT NULL DEFAULT 0;
ALTER TABLE map_owners ADD COLUMN wanted_by bigint;
