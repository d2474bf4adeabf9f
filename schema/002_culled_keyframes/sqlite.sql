-- orbatlas persistent atlas, schema version 2 (docs/schema.md): the anchors that
-- culled keyframes leave behind for Map::keyframe_pose, and the checkpoint
-- sequence number. Applied in one transaction by the migration runner.

-- A culled keyframe: its body pose relative to its spanning-tree parent at the
-- moment it was culled (the world pose T_w_b when it had no parent), so that
-- trajectory anchors referring to it still resolve, and follow later corrections
-- of the parent. The parent is a keyframe of the same map that may itself have
-- been culled since (a chain of culled keyframes): it names a row of `keyframes`
-- or of `culled_keyframes`, and moves from the first to the second when culled,
-- so it cannot be a foreign key. Loading checks that every chain ends at an
-- alive keyframe or a root of the same map.
CREATE TABLE culled_keyframes (
  id        INTEGER PRIMARY KEY CHECK (id >= 0),
  map_id    INTEGER NOT NULL REFERENCES maps(id) ON DELETE CASCADE,
  parent_id INTEGER CHECK (parent_id IS NULL OR (parent_id >= 0 AND parent_id <> id)),
  -- T_parent_b: the culled keyframe's body in its parent's body frame
  qw REAL NOT NULL, qx REAL NOT NULL, qy REAL NOT NULL, qz REAL NOT NULL,
  tx REAL NOT NULL, ty REAL NOT NULL, tz REAL NOT NULL,
  CHECK (abs(qw * qw + qx * qx + qy * qy + qz * qz - 1.0) < 1e-6)
) STRICT;
CREATE INDEX culled_keyframes_map ON culled_keyframes(map_id);

-- A keyframe id is alive or culled, never both.
CREATE TRIGGER culled_keyframes_not_alive BEFORE INSERT ON culled_keyframes
BEGIN
  SELECT RAISE(ABORT, 'culled keyframe: the id is an alive keyframe')
  WHERE EXISTS (SELECT 1 FROM keyframes WHERE id = NEW.id);
END;

CREATE TRIGGER keyframes_not_culled BEFORE INSERT ON keyframes
BEGIN
  SELECT RAISE(ABORT, 'keyframe: the id is a culled keyframe')
  WHERE EXISTS (SELECT 1 FROM culled_keyframes WHERE id = NEW.id);
END;

-- Incremented by every committed atlas write (save_atlas or a checkpoint), in the
-- same transaction: after a crash it names the last state that reached the file.
ALTER TABLE atlas ADD COLUMN checkpoint_seq INTEGER NOT NULL DEFAULT 0 CHECK (checkpoint_seq >= 0);

PRAGMA user_version = 2;
