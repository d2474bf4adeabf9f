-- orbatlas persistent atlas in PostgreSQL, schema version 1 (issue 23,
-- docs/schema.md). The same tables, columns and rules as SQLite's schema 8
-- (schema/001..008), in PostgreSQL's dialect:
--   * INTEGER -> bigint, REAL -> double precision, BLOB -> bytea, TEXT -> text;
--   * SQLite's NOT NULL on a REAL also rejects NaN (it stores NaN as NULL);
--     here each REAL column that SQLite keeps NOT NULL also CHECKs <> 'NaN';
--   * SQLite's triggers (RAISE(ABORT, ...)) are plpgsql functions raising an
--     exception with the same message;
--   * no STRICT / WITHOUT ROWID (PostgreSQL's columns are always typed).
-- Applied by the PostgreSQL migration runner (core/persistence/pg_schema.cc) in
-- one transaction, which also records it in schema_migrations.

CREATE TABLE schema_migrations (
  version    bigint PRIMARY KEY CHECK (version >= 1),
  name       text   NOT NULL,
  applied_ns bigint NOT NULL
);

CREATE TABLE maps (
  id       bigint PRIMARY KEY CHECK (id >= 0),
  saved_ns bigint NOT NULL
);

CREATE TABLE atlas (
  id                bigint PRIMARY KEY CHECK (id = 1),
  vocabulary_hash   text   NOT NULL CHECK (length(vocabulary_hash) > 0),
  created_ns        bigint NOT NULL,
  saved_ns          bigint,
  next_keyframe_id  bigint NOT NULL DEFAULT 0 CHECK (next_keyframe_id >= 0),
  next_map_point_id bigint NOT NULL DEFAULT 0 CHECK (next_map_point_id >= 0),
  next_map_id       bigint NOT NULL DEFAULT 0 CHECK (next_map_id >= 0),
  active_map_id     bigint REFERENCES maps(id) ON DELETE SET NULL,
  checkpoint_seq    bigint NOT NULL DEFAULT 0 CHECK (checkpoint_seq >= 0)
);

CREATE TABLE sessions (
  id         bigint PRIMARY KEY CHECK (id >= 0),
  name       text   NOT NULL,
  sensor     text   NOT NULL CHECK (sensor IN ('mono', 'stereo', 'mono_inertial', 'stereo_inertial', 'rgbd')),
  created_ns bigint NOT NULL
);

CREATE TABLE cameras (
  session_id   bigint NOT NULL REFERENCES sessions(id) ON DELETE CASCADE,
  camera_index bigint NOT NULL CHECK (camera_index >= 0),
  model        text   NOT NULL CHECK (model IN ('pinhole-radtan', 'kannala-brandt')),
  fx double precision NOT NULL CHECK (fx > 0 AND fx <> 'NaN'),
  fy double precision NOT NULL CHECK (fy > 0 AND fy <> 'NaN'),
  cx double precision NOT NULL CHECK (cx <> 'NaN'),
  cy double precision NOT NULL CHECK (cy <> 'NaN'),
  distortion   bytea  NOT NULL CHECK (length(distortion) % 8 = 0 AND length(distortion) <= 64),
  width        bigint NOT NULL CHECK (width > 0),
  height       bigint NOT NULL CHECK (height > 0),
  rate_hz      double precision NOT NULL CHECK (rate_hz >= 0 AND rate_hz <> 'NaN'),
  qw double precision NOT NULL, qx double precision NOT NULL, qy double precision NOT NULL,
  qz double precision NOT NULL,
  tx double precision NOT NULL CHECK (tx <> 'NaN'), ty double precision NOT NULL CHECK (ty <> 'NaN'),
  tz double precision NOT NULL CHECK (tz <> 'NaN'),
  CHECK (abs(qw * qw + qx * qx + qy * qy + qz * qz - 1.0) < 1e-6),
  PRIMARY KEY (session_id, camera_index)
);

CREATE TABLE keyframes (
  id           bigint PRIMARY KEY CHECK (id >= 0),
  map_id       bigint NOT NULL REFERENCES maps(id) ON DELETE CASCADE,
  session_id   bigint REFERENCES sessions(id) ON DELETE SET NULL,
  timestamp_ns bigint NOT NULL,
  qw double precision NOT NULL, qx double precision NOT NULL, qy double precision NOT NULL,
  qz double precision NOT NULL,
  tx double precision NOT NULL CHECK (tx <> 'NaN'), ty double precision NOT NULL CHECK (ty <> 'NaN'),
  tz double precision NOT NULL CHECK (tz <> 'NaN'),
  c_qw double precision NOT NULL, c_qx double precision NOT NULL, c_qy double precision NOT NULL,
  c_qz double precision NOT NULL,
  c_tx double precision NOT NULL CHECK (c_tx <> 'NaN'), c_ty double precision NOT NULL CHECK (c_ty <> 'NaN'),
  c_tz double precision NOT NULL CHECK (c_tz <> 'NaN'),
  parent_id    bigint REFERENCES keyframes(id) ON DELETE SET NULL DEFERRABLE INITIALLY DEFERRED,
  slot_count   bigint NOT NULL CHECK (slot_count >= 0),
  features     bytea  NOT NULL,
  units        double precision NOT NULL DEFAULT 1.0 CHECK (units > 0 AND units <> 'NaN'),
  CHECK (abs(qw * qw + qx * qx + qy * qy + qz * qz - 1.0) < 1e-6),
  CHECK (abs(c_qw * c_qw + c_qx * c_qx + c_qy * c_qy + c_qz * c_qz - 1.0) < 1e-6),
  CHECK (parent_id IS NULL OR parent_id <> id)
);
CREATE INDEX keyframes_map ON keyframes(map_id);
CREATE INDEX keyframes_session ON keyframes(session_id);
CREATE INDEX keyframes_parent ON keyframes(parent_id);

CREATE TABLE map_points (
  id           bigint PRIMARY KEY CHECK (id >= 0),
  map_id       bigint NOT NULL REFERENCES maps(id) ON DELETE CASCADE,
  x  double precision NOT NULL CHECK (x <> 'NaN'), y  double precision NOT NULL CHECK (y <> 'NaN'),
  z  double precision NOT NULL CHECK (z <> 'NaN'),
  nx double precision NOT NULL CHECK (nx <> 'NaN'), ny double precision NOT NULL CHECK (ny <> 'NaN'),
  nz double precision NOT NULL CHECK (nz <> 'NaN'),
  min_distance double precision NOT NULL CHECK (min_distance >= 0 AND min_distance <> 'NaN'),
  max_distance double precision NOT NULL CHECK (max_distance >= min_distance AND max_distance <> 'NaN'),
  descriptor   bytea  NOT NULL CHECK (length(descriptor) = 32),
  reference_keyframe_id bigint REFERENCES keyframes(id) ON DELETE SET NULL DEFERRABLE INITIALLY DEFERRED,
  visible      bigint NOT NULL,
  found        bigint NOT NULL
);
CREATE INDEX map_points_map ON map_points(map_id);
CREATE INDEX map_points_reference ON map_points(reference_keyframe_id);

CREATE TABLE observations (
  keyframe_id  bigint NOT NULL REFERENCES keyframes(id) ON DELETE CASCADE,
  slot         bigint NOT NULL CHECK (slot >= 0),
  map_point_id bigint NOT NULL REFERENCES map_points(id) ON DELETE CASCADE,
  PRIMARY KEY (keyframe_id, slot),
  UNIQUE (keyframe_id, map_point_id)
);
CREATE INDEX observations_map_point ON observations(map_point_id);

CREATE TABLE covisibility (
  keyframe_id bigint NOT NULL REFERENCES keyframes(id) ON DELETE CASCADE,
  other_id    bigint NOT NULL REFERENCES keyframes(id) ON DELETE CASCADE,
  weight      bigint NOT NULL CHECK (weight > 0),
  PRIMARY KEY (keyframe_id, other_id),
  CHECK (keyframe_id <> other_id)
);
CREATE INDEX covisibility_other ON covisibility(other_id);

CREATE TABLE loop_edges (
  keyframe_id bigint NOT NULL REFERENCES keyframes(id) ON DELETE CASCADE,
  other_id    bigint NOT NULL REFERENCES keyframes(id) ON DELETE CASCADE,
  PRIMARY KEY (keyframe_id, other_id),
  CHECK (keyframe_id < other_id)
);
CREATE INDEX loop_edges_other ON loop_edges(other_id);

CREATE TABLE trajectory (
  session_id            bigint NOT NULL REFERENCES sessions(id) ON DELETE CASCADE,
  t_ns                  bigint NOT NULL,
  map_id                bigint NOT NULL CHECK (map_id >= 0),
  reference_keyframe_id bigint NOT NULL CHECK (reference_keyframe_id >= 0),
  qw double precision NOT NULL, qx double precision NOT NULL, qy double precision NOT NULL,
  qz double precision NOT NULL,
  tx double precision NOT NULL CHECK (tx <> 'NaN'), ty double precision NOT NULL CHECK (ty <> 'NaN'),
  tz double precision NOT NULL CHECK (tz <> 'NaN'),
  CHECK (abs(qw * qw + qx * qx + qy * qy + qz * qz - 1.0) < 1e-6),
  PRIMARY KEY (session_id, t_ns)
);
CREATE INDEX trajectory_map ON trajectory(map_id);

CREATE TABLE culled_keyframes (
  id        bigint PRIMARY KEY CHECK (id >= 0),
  map_id    bigint NOT NULL REFERENCES maps(id) ON DELETE CASCADE,
  parent_id bigint CHECK (parent_id IS NULL OR (parent_id >= 0 AND parent_id <> id)),
  qw double precision NOT NULL, qx double precision NOT NULL, qy double precision NOT NULL,
  qz double precision NOT NULL,
  tx double precision NOT NULL CHECK (tx <> 'NaN'), ty double precision NOT NULL CHECK (ty <> 'NaN'),
  tz double precision NOT NULL CHECK (tz <> 'NaN'),
  units     double precision NOT NULL DEFAULT 1.0 CHECK (units > 0 AND units <> 'NaN'),
  CHECK (abs(qw * qw + qx * qx + qy * qy + qz * qz - 1.0) < 1e-6)
);
CREATE INDEX culled_keyframes_map ON culled_keyframes(map_id);

CREATE TABLE upload_jobs (
  id            bigint PRIMARY KEY CHECK (id >= 1),
  name          text   NOT NULL,
  state         text   NOT NULL CHECK (state IN ('queued', 'extracting', 'running', 'done', 'failed', 'cancelled')),
  session_id    bigint REFERENCES sessions(id) ON DELETE SET NULL,
  created_ns    bigint NOT NULL,
  archive_bytes bigint NOT NULL DEFAULT 0 CHECK (archive_bytes >= 0),
  frames_total  bigint NOT NULL DEFAULT 0 CHECK (frames_total >= 0),
  frames_done   bigint NOT NULL DEFAULT 0 CHECK (frames_done >= 0),
  tracked       bigint NOT NULL DEFAULT 0 CHECK (tracked >= 0),
  rejected      bigint NOT NULL DEFAULT 0 CHECK (rejected >= 0),
  ate_rmse_m    double precision,
  error         text   NOT NULL DEFAULT ''
);

CREATE TABLE keyframe_inertial_links (
  keyframe_id bigint PRIMARY KEY REFERENCES keyframes(id) ON DELETE CASCADE,
  previous_id bigint NOT NULL REFERENCES keyframes(id) ON DELETE CASCADE DEFERRABLE INITIALLY DEFERRED,
  increments  bytea  NOT NULL,
  c_i_qw double precision, c_i_qx double precision, c_i_qy double precision, c_i_qz double precision,
  c_i_tx double precision, c_i_ty double precision, c_i_tz double precision,
  CHECK (previous_id <> keyframe_id)
);
CREATE INDEX keyframe_inertial_links_previous ON keyframe_inertial_links(previous_id);

CREATE TABLE map_inertial_states (
  map_id            bigint PRIMARY KEY REFERENCES maps(id) ON DELETE CASCADE,
  initialized_at_ns bigint NOT NULL,
  gx double precision NOT NULL CHECK (gx <> 'NaN'), gy double precision NOT NULL CHECK (gy <> 'NaN'),
  gz double precision NOT NULL CHECK (gz <> 'NaN'),
  bgx double precision NOT NULL CHECK (bgx <> 'NaN'), bgy double precision NOT NULL CHECK (bgy <> 'NaN'),
  bgz double precision NOT NULL CHECK (bgz <> 'NaN'),
  bax double precision NOT NULL CHECK (bax <> 'NaN'), bay double precision NOT NULL CHECK (bay <> 'NaN'),
  baz double precision NOT NULL CHECK (baz <> 'NaN'),
  keyframes         bigint NOT NULL CHECK (keyframes >= 0),
  span_s            double precision NOT NULL CHECK (span_s >= 0.0 AND span_s <> 'NaN'),
  refinements       bigint NOT NULL DEFAULT 0 CHECK (refinements >= 0)
);

CREATE TABLE keyframe_imu_states (
  keyframe_id bigint PRIMARY KEY REFERENCES keyframes(id) ON DELETE CASCADE,
  vx double precision NOT NULL CHECK (vx <> 'NaN'), vy double precision NOT NULL CHECK (vy <> 'NaN'),
  vz double precision NOT NULL CHECK (vz <> 'NaN'),
  bgx double precision NOT NULL CHECK (bgx <> 'NaN'), bgy double precision NOT NULL CHECK (bgy <> 'NaN'),
  bgz double precision NOT NULL CHECK (bgz <> 'NaN'),
  bax double precision NOT NULL CHECK (bax <> 'NaN'), bay double precision NOT NULL CHECK (bay <> 'NaN'),
  baz double precision NOT NULL CHECK (baz <> 'NaN')
);

-- Relations that must stay inside one map (SQLite's triggers, as functions).
CREATE FUNCTION observations_same_map() RETURNS trigger LANGUAGE plpgsql AS $$
BEGIN
  IF NEW.slot >= (SELECT slot_count FROM keyframes WHERE id = NEW.keyframe_id)
     OR (SELECT map_id FROM keyframes WHERE id = NEW.keyframe_id)
        IS DISTINCT FROM (SELECT map_id FROM map_points WHERE id = NEW.map_point_id) THEN
    RAISE EXCEPTION 'observation: slot out of range or keyframe and map point in different maps';
  END IF;
  RETURN NEW;
END $$;
CREATE TRIGGER observations_same_map BEFORE INSERT ON observations
  FOR EACH ROW EXECUTE FUNCTION observations_same_map();

CREATE FUNCTION keyframe_pair_same_map() RETURNS trigger LANGUAGE plpgsql AS $$
BEGIN
  IF (SELECT map_id FROM keyframes WHERE id = NEW.keyframe_id)
     IS DISTINCT FROM (SELECT map_id FROM keyframes WHERE id = NEW.other_id) THEN
    RAISE EXCEPTION '%: keyframes in different maps', TG_ARGV[0];
  END IF;
  RETURN NEW;
END $$;
CREATE TRIGGER covisibility_same_map BEFORE INSERT ON covisibility
  FOR EACH ROW EXECUTE FUNCTION keyframe_pair_same_map('covisibility');
CREATE TRIGGER loop_edges_same_map BEFORE INSERT ON loop_edges
  FOR EACH ROW EXECUTE FUNCTION keyframe_pair_same_map('loop edge');

CREATE FUNCTION culled_keyframes_not_alive() RETURNS trigger LANGUAGE plpgsql AS $$
BEGIN
  IF EXISTS (SELECT 1 FROM keyframes WHERE id = NEW.id) THEN
    RAISE EXCEPTION 'culled keyframe: the id is an alive keyframe';
  END IF;
  RETURN NEW;
END $$;
CREATE TRIGGER culled_keyframes_not_alive BEFORE INSERT ON culled_keyframes
  FOR EACH ROW EXECUTE FUNCTION culled_keyframes_not_alive();

CREATE FUNCTION keyframes_not_culled() RETURNS trigger LANGUAGE plpgsql AS $$
BEGIN
  IF EXISTS (SELECT 1 FROM culled_keyframes WHERE id = NEW.id) THEN
    RAISE EXCEPTION 'keyframe: the id is a culled keyframe';
  END IF;
  RETURN NEW;
END $$;
CREATE TRIGGER keyframes_not_culled BEFORE INSERT ON keyframes
  FOR EACH ROW EXECUTE FUNCTION keyframes_not_culled();
