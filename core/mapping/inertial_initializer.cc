#include "core/mapping/inertial_initializer.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "core/common/error.h"
#include "core/common/log.h"

namespace orbatlas {

void InertialInitializationOptions::check() const {
  ORBATLAS_CHECK(std::isfinite(after_s) && after_s > 0.0,
                 "inertial initialisation: after_s must be > 0, not " << after_s);
  ORBATLAS_CHECK(min_keyframes >= 3, "inertial initialisation: min_keyframes must be >= 3, not " << min_keyframes);
  solver.check();
}

std::optional<Map::InertialState> initialize_map_inertial(Map& map, const std::shared_ptr<KeyFrame>& newest,
                                                          const InertialInitializationOptions& options, Atlas* atlas) {
  if (!options.enabled || map.inertial_state() || !newest || newest->is_bad()) return std::nullopt;
  const auto chain = inertial_chain(newest);
  if (chain.size() < options.min_keyframes) return std::nullopt;
  const double span_s = ns_to_s(chain.back()->timestamp_ns() - chain.front()->timestamp_ns());
  if (span_s < options.after_s) return std::nullopt;

  std::vector<Pose3> poses;
  std::vector<Preintegration> increments;
  for (std::size_t k = 0; k < chain.size(); ++k) {
    poses.push_back(chain[k]->T_w_b());
    if (k > 0) increments.push_back(*chain[k]->inertial_link()->from_previous);
  }
  // One linearisation point for the window (the session preintegrates at its
  // current estimate; before the first initialisation that is zero).
  for (auto& pre : increments)
    if (!(pre.bias() == increments.front().bias())) pre.reintegrate(increments.front().bias());
  const InertialInitResult result = initialize_inertial(poses, increments, options.T_b_i, options.solver);
  if (!result.gravity_w.allFinite() || result.final_cost > result.initial_cost) {
    log_warn("inertial initialisation of map " + std::to_string(map.id()) + " found no consistent solution (retried)");
    return std::nullopt;
  }
  // Each keyframe of the window starts with its velocity (in its IMU frame,
  // which the alignment below does not change) and the window's biases.
  for (std::size_t k = 0; k < chain.size() && k < result.velocities.size(); ++k) {
    const Eigen::Matrix3d R_w_i = (poses[k] * options.T_b_i).q.normalized().toRotationMatrix();
    chain[k]->set_imu_state(KeyFrame::ImuState{R_w_i.transpose() * result.velocities[k], result.bias});
  }
  Map::InertialState state;
  state.initialized_at_ns = newest->timestamp_ns();
  state.gravity_w = Eigen::Vector3d(0.0, 0.0, -options.solver.gravity);  // after the alignment below
  state.bias = result.bias;
  state.keyframes = chain.size();
  state.span_s = span_s;
  {
    // The map's frame becomes the gravity frame (its yaw kept): sessions tracking
    // in it see it before or after, never half-turned.
    std::unique_lock<WriterPriorityMutex> whole;
    if (atlas) whole = atlas->lock_maps_exclusive();
    map.change_frame(Pose3(Eigen::Quaterniond(result.R_w_g.transpose()), Eigen::Vector3d::Zero()));
    map.set_inertial_state(state);
  }
  std::ostringstream line;
  line << "inertial initialisation of map " << map.id() << ": " << chain.size() << " keyframes over " << span_s
       << " s; gravity was (" << result.gravity_w.transpose()
       << ") m/s^2 in the map, which now points it along -z; gyro bias (" << result.bias.gyro.transpose()
       << ") rad/s, accelerometer bias (" << result.bias.accel.transpose() << ") m/s^2; " << result.iterations
       << " iterations";
  log_info(line.str());
  return state;
}

}  // namespace orbatlas
