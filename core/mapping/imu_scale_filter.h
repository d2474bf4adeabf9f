#pragma once
// A map's estimate of its IMU's scale-factor correction (ImuScaleCorrection),
// fused from its visual-inertial local BAs in information form: each window's
// estimate weighs by what its inertial terms told of the correction
// (inertial_window_scale_information), shared among the windows a link is in
// (up to `overlap` of them), starting from a prior of `prior_sigma` per axis
// about no correction (a MEMS IMU's tolerance). An axis the motion does not
// excite keeps the prior; one it excites settles as the windows add up. One
// thread (the local mapper's).
#include <map>

#include "core/common/ids.h"
#include "core/imu/imu_noise.h"
#include "core/optimization/inertial_window.h"

namespace orbatlas {

struct ImuScaleFilterOptions {
  double prior_sigma = 0.005;
  double overlap = 10.0;         // windows a link is in (the temporal window's keyframes)
  double max_correction = 0.05;  // per axis: past any IMU's tolerance

  // Throws Error naming the first value out of range.
  void check() const;
};

class ImuScaleFilter {
 public:
  explicit ImuScaleFilter(ImuScaleFilterOptions options = {});

  // Fuses one window of `map` (its solved correction and information) into
  // the map's estimate `current`; returns the new estimate.
  ImuScaleCorrection add(MapId map, const ImuScaleCorrection& current, const ImuScaleCorrection& window,
                         const ImuScaleInformation& information);
  // The map's inertial state was dropped: its estimate starts again from the prior.
  void forget(MapId map) { information_.erase(map); }
  // The information the map's estimate holds (the prior's when none was added).
  ImuScaleInformation information(MapId map) const;

 private:
  ImuScaleFilterOptions options_;
  std::map<MapId, ImuScaleInformation> information_;
};

}  // namespace orbatlas
