-- orbatlas persistent atlas, schema version 4 (docs/schema.md): what a
-- visual-inertial map knows of its IMU (docs/inertial.md). Applied in one
-- transaction by the migration runner.

-- A keyframe's inertial link: the IMU preintegrated from the previous keyframe
-- of its session in its map (KeyFrame::inertial_link). Both keyframes are alive
-- keyframes of one map; culling the previous one joins the increments, which
-- rewrites this row (or deletes it when the chain breaks).
CREATE TABLE keyframe_inertial_links (
  keyframe_id INTEGER PRIMARY KEY REFERENCES keyframes(id) ON DELETE CASCADE,
  previous_id INTEGER NOT NULL REFERENCES keyframes(id) ON DELETE CASCADE DEFERRABLE INITIALLY DEFERRED,
  -- raw float64 array: version (1), gyro and accelerometer biases of the
  -- linearisation (6), the noise densities (4: gyro, accel, gyro walk, accel
  -- walk), then per measurement its gyro (3), accel (3) and dt (1)
  increments  BLOB NOT NULL,
  CHECK (previous_id <> keyframe_id)
) STRICT;
CREATE INDEX keyframe_inertial_links_previous ON keyframe_inertial_links(previous_id);

-- A map's inertial initialisation (Map::InertialState): gravity in the map's
-- frame and the IMU biases.
CREATE TABLE map_inertial_states (
  map_id            INTEGER PRIMARY KEY REFERENCES maps(id) ON DELETE CASCADE,
  initialized_at_ns INTEGER NOT NULL,
  gx REAL NOT NULL, gy REAL NOT NULL, gz REAL NOT NULL,
  bgx REAL NOT NULL, bgy REAL NOT NULL, bgz REAL NOT NULL,
  bax REAL NOT NULL, bay REAL NOT NULL, baz REAL NOT NULL,
  keyframes         INTEGER NOT NULL CHECK (keyframes >= 0),
  span_s            REAL NOT NULL CHECK (span_s >= 0.0)
) STRICT;

PRAGMA user_version = 4;
