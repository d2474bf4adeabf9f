-- orbatlas persistent atlas, schema version 7 (docs/schema.md): the scale of
-- lengths about each keyframe since it was made (KeyFrame::units, 1 in metric
-- maps; a monocular map's rescale, Sim(3) loop or merge changes it), so frame
-- anchors stored divided by it follow every later change of scale; and a
-- culled keyframe's units relative to its parent (a root's own units). Rows
-- written before version 7 are of units 1, which is what they were. Loading
-- refuses units that are not finite and > 0 too.

ALTER TABLE keyframes ADD COLUMN units REAL NOT NULL DEFAULT 1.0 CHECK (units > 0);
ALTER TABLE culled_keyframes ADD COLUMN units REAL NOT NULL DEFAULT 1.0 CHECK (units > 0);

PRAGMA user_version = 7;
