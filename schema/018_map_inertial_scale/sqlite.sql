-- orbatlas persistent atlas, schema version 18 (docs/schema.md): a map's
-- inertial state keeps the IMU's scale-factor correction its local BAs
-- estimated (Map::InertialState::scale, docs/inertial.md "The IMU's scale
-- factors"): per gyroscope axis (sgx..sgz) and accelerometer axis (sax..saz),
-- the true rate and specific force being 1 + s times the measurement less its
-- bias. A state written before this, or by a map that does not estimate them,
-- has 0 (no correction).
ALTER TABLE map_inertial_states ADD COLUMN sgx REAL NOT NULL DEFAULT 0.0;
ALTER TABLE map_inertial_states ADD COLUMN sgy REAL NOT NULL DEFAULT 0.0;
ALTER TABLE map_inertial_states ADD COLUMN sgz REAL NOT NULL DEFAULT 0.0;
ALTER TABLE map_inertial_states ADD COLUMN sax REAL NOT NULL DEFAULT 0.0;
ALTER TABLE map_inertial_states ADD COLUMN say REAL NOT NULL DEFAULT 0.0;
ALTER TABLE map_inertial_states ADD COLUMN saz REAL NOT NULL DEFAULT 0.0;

PRAGMA user_version = 18;
