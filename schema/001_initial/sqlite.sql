-- orbatlas persistent atlas, schema version 1 (docs/schema.md).
-- Applied by the migration runner (core/persistence/schema_migrations.cc) inside
-- one transaction when PRAGMA user_version is 0. The runner also records the
-- migration in schema_migrations and checks that user_version is 1 afterwards.
--
-- Conventions:
--   * ids are the atlas's 64-bit ids stored as INTEGER (always < 2^63, CHECKed >= 0);
--   * timestamps are int64 nanoseconds (sensor time for keyframes and trajectories,
--     Unix time for created_ns / saved_ns);
--   * a pose T_a_b is 7 REAL columns: unit quaternion qw qx qy qz, then tx ty tz;
--   * REAL columns are NOT NULL, which also rejects NaN (SQLite stores NaN as NULL);
--   * tables are STRICT (SQLite >= 3.37): a value of the wrong type is refused.

-- The atlas itself: exactly one row.
CREATE TABLE atlas (
  id                INTEGER PRIMARY KEY CHECK (id = 1),
  vocabulary_hash   TEXT    NOT NULL CHECK (length(vocabulary_hash) > 0),
  created_ns        INTEGER NOT NULL,
  saved_ns          INTEGER,            -- last save_atlas; NULL before the first
  -- The id allocator's next ids, so that ids of culled objects (still referenced
  -- by trajectories) are never handed out again after a reload.
  next_keyframe_id  INTEGER NOT NULL DEFAULT 0 CHECK (next_keyframe_id >= 0),
  next_map_point_id INTEGER NOT NULL DEFAULT 0 CHECK (next_map_point_id >= 0),
  next_map_id       INTEGER NOT NULL DEFAULT 0 CHECK (next_map_id >= 0),
  active_map_id     INTEGER REFERENCES maps(id) ON DELETE SET NULL
) STRICT;

-- One row per applied migration (PRAGMA user_version is the authority).
CREATE TABLE schema_migrations (
  version    INTEGER PRIMARY KEY CHECK (version >= 1),
  name       TEXT    NOT NULL,
  applied_ns INTEGER NOT NULL
) STRICT;

-- A recording / client session.
CREATE TABLE sessions (
  id         INTEGER PRIMARY KEY CHECK (id >= 0),
  name       TEXT    NOT NULL,
  sensor     TEXT    NOT NULL CHECK (sensor IN ('mono', 'stereo', 'mono_inertial', 'stereo_inertial')),
  created_ns INTEGER NOT NULL
) STRICT;

-- The camera rig of a session, one row per camera (index 0: left, 1: right).
-- Calibration as columns; the distortion coefficients, whose number depends on
-- the model, as a raw little-endian float64 array.
CREATE TABLE cameras (
  session_id   INTEGER NOT NULL REFERENCES sessions(id) ON DELETE CASCADE,
  camera_index INTEGER NOT NULL CHECK (camera_index >= 0),
  model        TEXT    NOT NULL CHECK (model IN ('pinhole-radtan', 'kannala-brandt')),
  fx REAL NOT NULL CHECK (fx > 0),
  fy REAL NOT NULL CHECK (fy > 0),
  cx REAL NOT NULL,
  cy REAL NOT NULL,
  distortion   BLOB    NOT NULL CHECK (length(distortion) % 8 = 0 AND length(distortion) <= 64),
  width        INTEGER NOT NULL CHECK (width > 0),
  height       INTEGER NOT NULL CHECK (height > 0),
  rate_hz      REAL    NOT NULL CHECK (rate_hz >= 0),
  -- T_b_c: the camera in the body (IMU) frame
  qw REAL NOT NULL, qx REAL NOT NULL, qy REAL NOT NULL, qz REAL NOT NULL,
  tx REAL NOT NULL, ty REAL NOT NULL, tz REAL NOT NULL,
  CHECK (abs(qw * qw + qx * qx + qy * qy + qz * qz - 1.0) < 1e-6),
  PRIMARY KEY (session_id, camera_index)
) STRICT, WITHOUT ROWID;

CREATE TABLE maps (
  id       INTEGER PRIMARY KEY CHECK (id >= 0),
  saved_ns INTEGER NOT NULL
) STRICT;

-- Alive keyframes only (culled ones are not stored).
CREATE TABLE keyframes (
  id           INTEGER PRIMARY KEY CHECK (id >= 0),
  map_id       INTEGER NOT NULL REFERENCES maps(id) ON DELETE CASCADE,
  session_id   INTEGER REFERENCES sessions(id) ON DELETE SET NULL,
  timestamp_ns INTEGER NOT NULL,
  -- T_w_b: body pose in the map's world
  qw REAL NOT NULL, qx REAL NOT NULL, qy REAL NOT NULL, qz REAL NOT NULL,
  tx REAL NOT NULL, ty REAL NOT NULL, tz REAL NOT NULL,
  -- T_b_c: the (left) camera in the body
  c_qw REAL NOT NULL, c_qx REAL NOT NULL, c_qy REAL NOT NULL, c_qz REAL NOT NULL,
  c_tx REAL NOT NULL, c_ty REAL NOT NULL, c_tz REAL NOT NULL,
  -- spanning tree; NULL for a root. Deferred: a parent may be written after its child.
  parent_id    INTEGER REFERENCES keyframes(id) ON DELETE SET NULL DEFERRABLE INITIALLY DEFERRED,
  slot_count   INTEGER NOT NULL CHECK (slot_count >= 0),  -- keypoints = map point slots
  features     BLOB    NOT NULL,  -- Cereal binary, leading u32 version tag (docs/schema.md)
  CHECK (abs(qw * qw + qx * qx + qy * qy + qz * qz - 1.0) < 1e-6),
  CHECK (abs(c_qw * c_qw + c_qx * c_qx + c_qy * c_qy + c_qz * c_qz - 1.0) < 1e-6),
  CHECK (parent_id IS NULL OR parent_id <> id)
) STRICT;
CREATE INDEX keyframes_map ON keyframes(map_id);
CREATE INDEX keyframes_session ON keyframes(session_id);
CREATE INDEX keyframes_parent ON keyframes(parent_id);

-- Alive map points only.
CREATE TABLE map_points (
  id           INTEGER PRIMARY KEY CHECK (id >= 0),
  map_id       INTEGER NOT NULL REFERENCES maps(id) ON DELETE CASCADE,
  x  REAL NOT NULL, y  REAL NOT NULL, z  REAL NOT NULL,  -- position in the map's world
  nx REAL NOT NULL, ny REAL NOT NULL, nz REAL NOT NULL,  -- mean viewing direction
  min_distance REAL NOT NULL CHECK (min_distance >= 0),
  max_distance REAL NOT NULL CHECK (max_distance >= min_distance),
  descriptor   BLOB NOT NULL CHECK (length(descriptor) = 32),  -- 256 bits, 4 little-endian u64
  reference_keyframe_id INTEGER REFERENCES keyframes(id) ON DELETE SET NULL DEFERRABLE INITIALLY DEFERRED,
  visible      INTEGER NOT NULL,  -- tracking statistics (ORB-SLAM's visible / found)
  found        INTEGER NOT NULL
) STRICT;
CREATE INDEX map_points_map ON map_points(map_id);
CREATE INDEX map_points_reference ON map_points(reference_keyframe_id);

-- Keyframe slot -> map point. A point sits in at most one slot of a keyframe.
CREATE TABLE observations (
  keyframe_id  INTEGER NOT NULL REFERENCES keyframes(id) ON DELETE CASCADE,
  slot         INTEGER NOT NULL CHECK (slot >= 0),
  map_point_id INTEGER NOT NULL REFERENCES map_points(id) ON DELETE CASCADE,
  PRIMARY KEY (keyframe_id, slot),
  UNIQUE (keyframe_id, map_point_id)
) STRICT, WITHOUT ROWID;
CREATE INDEX observations_map_point ON observations(map_point_id);

-- Covisibility as each keyframe holds it: directed, because a neighbour keeps its
-- older mirrored weight until it updates its own connections (docs/map_model.md).
CREATE TABLE covisibility (
  keyframe_id INTEGER NOT NULL REFERENCES keyframes(id) ON DELETE CASCADE,
  other_id    INTEGER NOT NULL REFERENCES keyframes(id) ON DELETE CASCADE,
  weight      INTEGER NOT NULL CHECK (weight > 0),
  PRIMARY KEY (keyframe_id, other_id),
  CHECK (keyframe_id <> other_id)
) STRICT, WITHOUT ROWID;
CREATE INDEX covisibility_other ON covisibility(other_id);

-- Loop edges are symmetric in memory: stored once, lower id first.
CREATE TABLE loop_edges (
  keyframe_id INTEGER NOT NULL REFERENCES keyframes(id) ON DELETE CASCADE,
  other_id    INTEGER NOT NULL REFERENCES keyframes(id) ON DELETE CASCADE,
  PRIMARY KEY (keyframe_id, other_id),
  CHECK (keyframe_id < other_id)
) STRICT, WITHOUT ROWID;
CREATE INDEX loop_edges_other ON loop_edges(other_id);

-- Per-frame trajectory of a session: each frame relative to its reference
-- keyframe (tracking's FrameAnchor). No foreign key to keyframes or maps: the
-- reference may have been culled since, and a trajectory may be saved first.
CREATE TABLE trajectory (
  session_id            INTEGER NOT NULL REFERENCES sessions(id) ON DELETE CASCADE,
  t_ns                  INTEGER NOT NULL,
  map_id                INTEGER NOT NULL CHECK (map_id >= 0),
  reference_keyframe_id INTEGER NOT NULL CHECK (reference_keyframe_id >= 0),
  -- T_ref_b: the body in the reference keyframe's body frame
  qw REAL NOT NULL, qx REAL NOT NULL, qy REAL NOT NULL, qz REAL NOT NULL,
  tx REAL NOT NULL, ty REAL NOT NULL, tz REAL NOT NULL,
  CHECK (abs(qw * qw + qx * qx + qy * qy + qz * qz - 1.0) < 1e-6),
  PRIMARY KEY (session_id, t_ns)
) STRICT, WITHOUT ROWID;
CREATE INDEX trajectory_map ON trajectory(map_id);

-- Relations that must stay inside one map (a CHECK cannot look at other rows).
CREATE TRIGGER observations_same_map BEFORE INSERT ON observations
BEGIN
  SELECT RAISE(ABORT, 'observation: slot out of range or keyframe and map point in different maps')
  WHERE NEW.slot >= (SELECT slot_count FROM keyframes WHERE id = NEW.keyframe_id)
     OR (SELECT map_id FROM keyframes WHERE id = NEW.keyframe_id)
        IS NOT (SELECT map_id FROM map_points WHERE id = NEW.map_point_id);
END;

CREATE TRIGGER covisibility_same_map BEFORE INSERT ON covisibility
BEGIN
  SELECT RAISE(ABORT, 'covisibility: keyframes in different maps')
  WHERE (SELECT map_id FROM keyframes WHERE id = NEW.keyframe_id)
        IS NOT (SELECT map_id FROM keyframes WHERE id = NEW.other_id);
END;

CREATE TRIGGER loop_edges_same_map BEFORE INSERT ON loop_edges
BEGIN
  SELECT RAISE(ABORT, 'loop edge: keyframes in different maps')
  WHERE (SELECT map_id FROM keyframes WHERE id = NEW.keyframe_id)
        IS NOT (SELECT map_id FROM keyframes WHERE id = NEW.other_id);
END;

PRAGMA user_version = 1;
