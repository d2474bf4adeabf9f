-- orbatlas persistent atlas, schema version 5 (docs/schema.md): each keyframe's
-- IMU state in a visual-inertial map and the refinements of the map's inertial
-- initialisation (docs/inertial.md). Applied in one
-- transaction by the migration runner.

-- KeyFrame::imu_state: the IMU's velocity in the IMU's own frame at the
-- keyframe (so that moving the map or the keyframe carries it along) and the
-- gyro and accelerometer biases, as visual-inertial BA last left them.
CREATE TABLE keyframe_imu_states (
  keyframe_id INTEGER PRIMARY KEY REFERENCES keyframes(id) ON DELETE CASCADE,
  vx REAL NOT NULL, vy REAL NOT NULL, vz REAL NOT NULL,
  bgx REAL NOT NULL, bgy REAL NOT NULL, bgz REAL NOT NULL,
  bax REAL NOT NULL, bay REAL NOT NULL, baz REAL NOT NULL
) STRICT;

-- The refinements of a map's inertial initialisation done so far (at 5 s and
-- 15 s after it; docs/inertial.md).
ALTER TABLE map_inertial_states ADD COLUMN refinements INTEGER NOT NULL DEFAULT 0 CHECK (refinements >= 0);

PRAGMA user_version = 5;
