#pragma once
// Whether a map's IMU still agrees with its vision. After each visual-inertial
// local BA the median chi2 of the window's inertial links (9 degrees of
// freedom; a consistent IMU with the vibration-aware noise gives about 3) is
// fed in; when the median of the latest `window` of them (three of five)
// exceeds `max_median_chi2`, the IMU is bending the map rather than helping it (a bias
// that jumped, a mounting or a scale far from the calibration's): the map's
// inertial state is dropped and it is tracked and adjusted by vision alone
// until its inertial initialisation, which checks its own answer, succeeds
// again, from the keyframes after the reset only; with loop closing a visual
// global BA straightens what the IMU bent. After `max_resets` such resets the
// map stays visual. One thread (the local mapper's).
#include <cstddef>
#include <deque>
#include <map>

#include "core/common/ids.h"

namespace orbatlas {

struct InertialConsistencyOptions {
  bool enabled = true;
  std::size_t window = 5;         // local BAs
  double max_median_chi2 = 30.0;  // ten times a consistent IMU's
  std::size_t max_resets = 2;

  // Throws Error naming the first value out of range.
  void check() const;
};

class InertialConsistency {
 public:
  explicit InertialConsistency(InertialConsistencyOptions options = {});

  enum class Verdict {
    kKeep,    // the IMU agrees (or too few BAs yet to tell)
    kReset,   // drop the map's inertial state; it may be initialised again
    kGiveUp,  // drop it for good: the map stays visual
  };
  // A local BA of `map` whose inertial links ended with this median chi2.
  Verdict add(MapId map, double median_chi2);
  // The median over the latest window of `map` (0 before any).
  double recent_median(MapId map) const;
  // Whether `map`'s IMU was given up (its initialisation is not tried again).
  bool given_up(MapId map) const;

 private:
  struct PerMap {
    std::deque<double> recent;
    std::size_t resets = 0;
    bool given_up = false;
  };
  InertialConsistencyOptions options_;
  std::map<MapId, PerMap> maps_;
};

}  // namespace orbatlas
