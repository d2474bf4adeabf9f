#pragma once
// How many keyframes and map points an atlas has created, culled (removed from
// their map) and reclaimed (destroyed: memory freed). Every object holds the
// counters through a shared_ptr, so they outlive the atlas and its objects.
#include <array>
#include <atomic>
#include <cstdint>
#include <memory>

namespace orbatlas {

enum class ObjectKind { keyframe = 0, map_point = 1 };

struct CounterSnapshot {
  std::uint64_t created = 0;
  std::uint64_t culled = 0;
  std::uint64_t reclaimed = 0;
  std::uint64_t alive() const { return created - reclaimed; }
};

class ObjectCounters {
 public:
  void on_created(ObjectKind kind) { at(kind).created.fetch_add(1); }
  void on_culled(ObjectKind kind) { at(kind).culled.fetch_add(1); }
  void on_reclaimed(ObjectKind kind) { at(kind).reclaimed.fetch_add(1); }

  // Reads reclaimed before created, so alive() never underflows.
  CounterSnapshot snapshot(ObjectKind kind) const;
  CounterSnapshot keyframes() const { return snapshot(ObjectKind::keyframe); }
  CounterSnapshot map_points() const { return snapshot(ObjectKind::map_point); }

 private:
  struct Kind {
    std::atomic<std::uint64_t> created{0}, culled{0}, reclaimed{0};
  };
  Kind& at(ObjectKind kind) { return kinds_[static_cast<std::size_t>(kind)]; }
  const Kind& at(ObjectKind kind) const { return kinds_[static_cast<std::size_t>(kind)]; }
  std::array<Kind, 2> kinds_;
};

// The FIRST member of a KeyFrame / MapPoint: constructed first (counts
// "created") and destroyed last, after every other member has released its
// memory (counts "reclaimed").
class LifetimeToken {
 public:
  LifetimeToken(std::shared_ptr<ObjectCounters> counters, ObjectKind kind);
  ~LifetimeToken();
  LifetimeToken(const LifetimeToken&) = delete;
  LifetimeToken& operator=(const LifetimeToken&) = delete;

  ObjectCounters& counters() const { return *counters_; }

 private:
  std::shared_ptr<ObjectCounters> counters_;
  ObjectKind kind_;
};

}  // namespace orbatlas
