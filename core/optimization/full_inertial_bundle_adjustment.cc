#include "core/optimization/full_inertial_bundle_adjustment.h"

#include "core/common/error.h"

namespace orbatlas {

GlobalBundleAdjustmentResult full_inertial_bundle_adjustment(Map& map, const Camera& camera, double bf,
                                                             const GlobalBundleAdjustmentOptions& options) {
  ORBATLAS_CHECK(options.inertial.has_value(), "full visual-inertial BA: the IMU's options are missing");
  GlobalBundleAdjustmentResult result = global_bundle_adjustment(map, camera, bf, options);
  for (const auto& kf : map.keyframes()) {
    if (kf->is_bad()) continue;
    if (const auto it = result.T_w_b.find(kf->id()); it != result.T_w_b.end()) kf->set_T_w_b(it->second);
    if (const auto it = result.imu_states.find(kf->id()); it != result.imu_states.end()) kf->set_imu_state(it->second);
  }
  for (const auto& mp : map.map_points()) {
    if (mp->is_bad()) continue;
    if (const auto it = result.p_w.find(mp->id()); it != result.p_w.end()) mp->set_p_w(it->second);
  }
  return result;
}

}  // namespace orbatlas
