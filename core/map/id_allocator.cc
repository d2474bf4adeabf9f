#include "core/map/id_allocator.h"

#include <limits>

#include "core/common/error.h"

namespace orbatlas {

std::uint64_t IdAllocator::next(IdKind kind) {
  const std::uint64_t id = counter(kind).fetch_add(1, std::memory_order_relaxed);
  ORBATLAS_CHECK(id != std::numeric_limits<std::uint64_t>::max(), "IdAllocator: ids exhausted");
  return id;
}

std::uint64_t IdAllocator::peek(IdKind kind) const { return counter(kind).load(std::memory_order_relaxed); }

void IdAllocator::ensure_above(IdKind kind, std::uint64_t max_used) {
  ORBATLAS_CHECK(max_used != std::numeric_limits<std::uint64_t>::max(),
                 "IdAllocator: loaded id " << max_used << " leaves no room");
  std::atomic<std::uint64_t>& c = counter(kind);
  std::uint64_t current = c.load(std::memory_order_relaxed);
  while (current <= max_used && !c.compare_exchange_weak(current, max_used + 1, std::memory_order_relaxed)) {
  }
}

}  // namespace orbatlas
