-- orbatlas persistent atlas in PostgreSQL, schema version 5 (issue 23,
-- docs/scaling.md "Replicas"): upload jobs as a queue every replica takes
-- from. A replica that received an upload (extracted into the work folder the
-- replicas share) adds its job here; a free worker of any replica claims the
-- oldest unclaimed one (FOR UPDATE SKIP LOCKED: two workers never take one
-- job); the jobs of a replica whose lease has passed are unclaimed again and
-- run by another. upload_jobs keeps each job's state and figures, as on SQLite.
-- PostgreSQL only: an SQLite atlas has one server.

CREATE TABLE shared_jobs (
  job_id     bigint PRIMARY KEY REFERENCES upload_jobs(id) ON DELETE CASCADE,
  replica_id bigint,                -- the replica running it; NULL: waiting
  folder     text   NOT NULL,       -- the extracted upload, in the shared work folder
  request    text   NOT NULL,       -- the session request (JSON: name, config, settings_yaml, sensor, mode)
  claimed_ns bigint
);
CREATE INDEX shared_jobs_waiting ON shared_jobs(job_id) WHERE replica_id IS NULL;
