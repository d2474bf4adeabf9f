-- orbatlas persistent atlas in PostgreSQL, schema version 18 (sqlite.sql beside
-- this file, docs/schema.md): a map's inertial state keeps the IMU's
-- scale-factor correction its local BAs estimated.
ALTER TABLE map_inertial_states ADD COLUMN sgx double precision NOT NULL DEFAULT 0 CHECK (sgx <> 'NaN');
ALTER TABLE map_inertial_states ADD COLUMN sgy double precision NOT NULL DEFAULT 0 CHECK (sgy <> 'NaN');
ALTER TABLE map_inertial_states ADD COLUMN sgz double precision NOT NULL DEFAULT 0 CHECK (sgz <> 'NaN');
ALTER TABLE map_inertial_states ADD COLUMN sax double precision NOT NULL DEFAULT 0 CHECK (sax <> 'NaN');
ALTER TABLE map_inertial_states ADD COLUMN say double precision NOT NULL DEFAULT 0 CHECK (say <> 'NaN');
ALTER TABLE map_inertial_states ADD COLUMN saz double precision NOT NULL DEFAULT 0 CHECK (saz <> 'NaN');
