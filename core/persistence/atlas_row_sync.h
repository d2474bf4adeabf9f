#pragma once
// Brings the stored rows of an atlas from one state to another: writes the rows
// that are new or whose content hash changed, and deletes the rows of objects
// that are gone. The full save is the special case of an empty previous state.
#include <cstddef>

#include "core/common/timestamp.h"
#include "core/persistence/atlas_row_writer.h"
#include "core/persistence/atlas_rows.h"

namespace orbatlas {

struct RowCounts {
  std::size_t inserted = 0, updated = 0, deleted = 0;
  std::size_t total() const { return inserted + updated + deleted; }
  RowCounts& operator+=(const RowCounts& other) {
    inserted += other.inserted;
    updated += other.updated;
    deleted += other.deleted;
    return *this;
  }
};

// `before` must be what the database holds for these objects (the rows last
// committed, or nothing when the maps' stored rows were deleted first). Order:
// maps rows of new maps; deletions, children before parents (observations,
// covisibility and loop edges, map points, keyframes, culled keyframes); then
// inserts and updates, parents before children. Rows that cascade away with a
// deleted keyframe (its observations and its own covisibility rows) are counted
// as deleted without a statement each. An observation whose slot now holds
// another point is deleted and inserted again (counted as updated), so that a
// point moving between slots of one keyframe never meets UNIQUE(keyframe, point).
// The atlas row is left to AtlasRowWriter::write_meta.
RowCounts write_changed_rows(AtlasRowWriter& writer, const AtlasRows& before, const AtlasRows& now,
                             TimestampNs saved_ns);

// True when the atlas row's content (allocator, active map) differs.
bool meta_changed(const AtlasRows& before, const AtlasRows& now);

}  // namespace orbatlas
