#include "core/map/object_counters.h"

#include "core/common/error.h"

namespace orbatlas {

CounterSnapshot ObjectCounters::snapshot(ObjectKind kind) const {
  const Kind& k = at(kind);
  CounterSnapshot s;
  s.reclaimed = k.reclaimed.load();
  s.culled = k.culled.load();
  s.created = k.created.load();
  return s;
}

LifetimeToken::LifetimeToken(std::shared_ptr<ObjectCounters> counters, ObjectKind kind)
    : counters_(std::move(counters)), kind_(kind) {
  ORBATLAS_CHECK(counters_ != nullptr, "map object created without counters");
  counters_->on_created(kind_);
}

LifetimeToken::~LifetimeToken() { counters_->on_reclaimed(kind_); }

}  // namespace orbatlas
