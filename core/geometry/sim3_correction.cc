#include "core/geometry/sim3_correction.h"

namespace orbatlas {

Sim3 propagate_correction(const Pose3& T_i_w_old, const Pose3& T_c_w_old, const Sim3& S_c_w_new) {
  return Sim3(T_i_w_old * T_c_w_old.inverse()) * S_c_w_new;
}

Eigen::Vector3d correct_point(const Pose3& T_c_w_old, const Sim3& S_c_w_new, const Eigen::Vector3d& p_w_old) {
  return S_c_w_new.inverse() * (T_c_w_old * p_w_old);
}

Pose3 rigid_pose_c_w(const Sim3& S_c_w) { return Pose3(S_c_w.q, S_c_w.t / S_c_w.s); }

}  // namespace orbatlas
