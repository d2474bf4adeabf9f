#pragma once
// Per-atlas id source: one atomic counter per kind of object, so ids are unique
// in the whole atlas (across its maps) without any process-wide state.
#include <array>
#include <atomic>
#include <cstdint>

#include "core/common/ids.h"

namespace orbatlas {

enum class IdKind { keyframe, map_point, map };

class IdAllocator {
 public:
  KeyframeId next_keyframe_id() { return next(IdKind::keyframe); }
  MapPointId next_map_point_id() { return next(IdKind::map_point); }
  MapId next_map_id() { return next(IdKind::map); }

  std::uint64_t next(IdKind kind);
  // The id next() would hand out now (for reports and tests).
  std::uint64_t peek(IdKind kind) const;
  // Re-seed after loading stored objects: every later id of `kind` is > max_used.
  // Once confined, ids outside the range are ignored (another writer's).
  void ensure_above(IdKind kind, std::uint64_t max_used);
  // Several writers of one database (replicas): from now on ids of
  // `kind` come from [begin, end) only, the range this writer has to itself
  // (next() throws Error when it is used up). Ids already handed out in the
  // range are skipped. Call before the allocator is shared with other threads.
  void confine(IdKind kind, std::uint64_t begin, std::uint64_t end);

 private:
  std::atomic<std::uint64_t>& counter(IdKind kind) { return next_[static_cast<std::size_t>(kind)]; }
  const std::atomic<std::uint64_t>& counter(IdKind kind) const { return next_[static_cast<std::size_t>(kind)]; }

  std::array<std::atomic<std::uint64_t>, 3> next_{};  // indexed by IdKind; ids start at 0
  struct Range {
    std::uint64_t begin = 0, end = ~std::uint64_t{0};
  };
  std::array<Range, 3> ranges_{};  // set by confine() only, before any concurrent use
};

}  // namespace orbatlas
