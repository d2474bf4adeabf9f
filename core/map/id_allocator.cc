#include "core/map/id_allocator.h"

#include <limits>

#include "core/common/error.h"

namespace orbatlas {

std::uint64_t IdAllocator::next(IdKind kind) {
  const std::uint64_t id = counter(kind).fetch_add(1, std::memory_order_relaxed);
  ORBATLAS_CHECK(id != std::numeric_limits<std::uint64_t>::max(), "IdAllocator: ids exhausted");
  ORBATLAS_CHECK(id < ranges_[static_cast<std::size_t>(kind)].end,
                 "IdAllocator: this writer's range of ids is used up (up to "
                     << ranges_[static_cast<std::size_t>(kind)].end << "): restart it for a new one");
  return id;
}

std::uint64_t IdAllocator::peek(IdKind kind) const { return counter(kind).load(std::memory_order_relaxed); }

void IdAllocator::ensure_above(IdKind kind, std::uint64_t max_used) {
  ORBATLAS_CHECK(max_used != std::numeric_limits<std::uint64_t>::max(),
                 "IdAllocator: loaded id " << max_used << " leaves no room");
  const Range& range = ranges_[static_cast<std::size_t>(kind)];
  if (max_used < range.begin || max_used >= range.end) {
    // Outside a confined range: another writer's id. Unconfined, the range is everything.
    return;
  }
  std::atomic<std::uint64_t>& c = counter(kind);
  std::uint64_t current = c.load(std::memory_order_relaxed);
  while (current <= max_used && !c.compare_exchange_weak(current, max_used + 1, std::memory_order_relaxed)) {
  }
}

void IdAllocator::confine(IdKind kind, std::uint64_t begin, std::uint64_t end) {
  ORBATLAS_CHECK(begin < end, "IdAllocator: empty range [" << begin << ", " << end << ")");
  ranges_[static_cast<std::size_t>(kind)] = Range{begin, end};
  std::atomic<std::uint64_t>& c = counter(kind);
  const std::uint64_t current = c.load(std::memory_order_relaxed);
  if (current < begin || current >= end) c.store(begin, std::memory_order_relaxed);
}

}  // namespace orbatlas
