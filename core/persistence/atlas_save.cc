// AtlasStore::save_atlas: every map of the atlas replaces its stored rows, in one
// write transaction (all or nothing). The rows are those a checkpoint writes
// (atlas_rows.h), written by the same code with nothing to compare against.
#include <algorithm>

#include "core/persistence/atlas_row_sync.h"
#include "core/persistence/atlas_store.h"
#include "core/persistence/wall_clock.h"

namespace orbatlas {

void AtlasStore::save_atlas(const Atlas& atlas, const AtlasSaveOptions& options) {
  const TimestampNs now = unix_time_ns();
  SqlTransaction transaction(*db_);
  {
    AtlasRowWriter writer(*db_);  // its statements are finalized before COMMIT
    // A keyframe not listed keeps the session stored for it.
    const std::unordered_map<KeyframeId, SessionId> stored = writer.stored_keyframe_sessions();
    const AtlasRows rows = collect_atlas_rows(atlas, [&](KeyframeId id) -> std::optional<SessionId> {
      if (const auto it = options.keyframe_sessions.find(id); it != options.keyframe_sessions.end()) return it->second;
      if (const auto it = stored.find(id); it != stored.end()) return it->second;
      return std::nullopt;
    });
    {
      // Maps merged into others since loading go; other stored maps stay.
      for (const MapId map : atlas.removed_maps()) writer.delete_map(map);
      for (const MapId map : rows.maps) writer.delete_map_contents(map);
    }
    write_changed_rows(writer, AtlasRows{}, rows, now);
    writer.write_meta(*rows.meta, now);
  }
  transaction.commit();
}

}  // namespace orbatlas
