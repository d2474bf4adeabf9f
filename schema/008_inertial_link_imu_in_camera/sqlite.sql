-- orbatlas persistent atlas, schema version 8 (docs/schema.md): the IMU in the
-- keyframe's camera (T_c_i) of each inertial link, so that one map can hold
-- the chains of sessions whose IMU sits differently in their body (a single
-- camera's body is its camera, a stereo rig's its IMU) and each chain's
-- visual-inertial terms use their own. All seven NULL: a link stored before
-- version 8, whose IMU is placed by the map's session settings as before.

ALTER TABLE keyframe_inertial_links ADD COLUMN c_i_qw REAL;
ALTER TABLE keyframe_inertial_links ADD COLUMN c_i_qx REAL;
ALTER TABLE keyframe_inertial_links ADD COLUMN c_i_qy REAL;
ALTER TABLE keyframe_inertial_links ADD COLUMN c_i_qz REAL;
ALTER TABLE keyframe_inertial_links ADD COLUMN c_i_tx REAL;
ALTER TABLE keyframe_inertial_links ADD COLUMN c_i_ty REAL;
ALTER TABLE keyframe_inertial_links ADD COLUMN c_i_tz REAL;

PRAGMA user_version = 8;
