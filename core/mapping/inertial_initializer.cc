#include "core/mapping/inertial_initializer.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>

#include "core/common/error.h"
#include "core/common/log.h"
#include "core/imu/turn_about_gravity.h"

namespace orbatlas {

void InertialInitializationOptions::check() const {
  ORBATLAS_CHECK(std::isfinite(after_s) && after_s > 0.0,
                 "inertial initialisation: after_s must be > 0, not " << after_s);
  ORBATLAS_CHECK(min_keyframes >= 3, "inertial initialisation: min_keyframes must be >= 3, not " << min_keyframes);
  ORBATLAS_CHECK(
      refinement_max_keyframes >= min_keyframes,
      "inertial initialisation: refinement_max_keyframes must be >= min_keyframes, not " << refinement_max_keyframes);
  double previous_s = 0.0;
  for (const InertialRefinement& r : refinements) {
    ORBATLAS_CHECK(std::isfinite(r.after_s) && r.after_s > previous_s,
                   "inertial initialisation: refinement times must increase from > 0 s, not " << r.after_s);
    ORBATLAS_CHECK(std::isfinite(r.gyro_bias_prior) && r.gyro_bias_prior >= 0.0 && std::isfinite(r.accel_bias_prior) &&
                       r.accel_bias_prior >= 0.0,
                   "inertial initialisation: a refinement's bias priors must be >= 0");
    previous_s = r.after_s;
  }
  ORBATLAS_CHECK(
      std::isfinite(refinement_min_span_fraction) && refinement_min_span_fraction >= 0.0,
      "inertial initialisation: refinement_min_span_fraction must be >= 0, not " << refinement_min_span_fraction);
  ORBATLAS_CHECK(
      std::isfinite(min_turn_to_free_accel_bias_deg) && min_turn_to_free_accel_bias_deg >= 0.0,
      "inertial initialisation: min_turn_to_free_accel_bias_deg must be >= 0, not " << min_turn_to_free_accel_bias_deg);
  ORBATLAS_CHECK(std::isfinite(held_accel_bias_prior) && held_accel_bias_prior > 0.0,
                 "inertial initialisation: held_accel_bias_prior must be > 0, not " << held_accel_bias_prior);
  ORBATLAS_CHECK(
      std::isfinite(reintegrate_gyro_bias_change) && reintegrate_gyro_bias_change >= 0.0,
      "inertial initialisation: reintegrate_gyro_bias_change must be >= 0, not " << reintegrate_gyro_bias_change);
  for (const auto& [name, value] :
       {std::pair{"max_gyro_bias", max_gyro_bias}, std::pair{"max_accel_bias", max_accel_bias},
        std::pair{"max_median_link_chi2", max_median_link_chi2},
        std::pair{"max_median_rotation_chi2", max_median_rotation_chi2},
        std::pair{"max_refinement_turn_deg", max_refinement_turn_deg}})
    ORBATLAS_CHECK(std::isfinite(value) && value > 0.0,
                   "inertial initialisation: " << name << " must be a finite value > 0, not " << value);
  solver.check();
}

namespace {

// Integrates again, at `bias`, every link of `chain` linearised at a gyro bias
// more than `max_change` from it; returns how many.
std::size_t reintegrate_far_links(const std::vector<std::shared_ptr<KeyFrame>>& chain, const ImuBias& bias,
                                  double max_change) {
  std::size_t count = 0;
  for (std::size_t k = 1; k < chain.size(); ++k) {
    const auto link = chain[k]->inertial_link();
    const auto previous = link ? link->previous.lock() : nullptr;
    if (!previous || !link->from_previous || (link->from_previous->bias().gyro - bias.gyro).norm() <= max_change)
      continue;
    auto again = std::make_shared<Preintegration>(*link->from_previous);
    again->reintegrate(bias);
    chain[k]->set_inertial_link(previous, std::move(again), link->T_c_i);
    ++count;
  }
  return count;
}

// The inertial-only estimate over `chain` (with `solver`'s bias priors) and,
// when it is consistent, its application: each keyframe's velocity (in its IMU
// frame, which the alignment does not change) and biases, then the map turned
// so that gravity points along -z (its yaw kept) and `state` (biases filled in
// here) set. `what` names the step in the log.
double median_of(std::vector<double> values) {
  if (values.empty()) return 0.0;
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2), values.end());
  return values[values.size() / 2];
}

// How far the gravity found is from the map's current one (-z before the
// initialisation, which turns the map to it).
double gravity_turn_deg(const InertialInitResult& r, const Eigen::Vector3d& current_gravity_w) {
  return std::atan2(r.gravity_w.cross(current_gravity_w).norm(), r.gravity_w.dot(current_gravity_w)) * 180.0 / M_PI;
}

// Why an estimate is not to be kept (empty: it may be): biases out of range,
// inertial residuals that do not fit, a refinement that would turn the map far.
std::string implausible(const InertialInitResult& r, const InertialInitializationOptions& options,
                        const InertialInitOptions& solver, bool refinement, const Eigen::Vector3d& current_gravity_w) {
  std::ostringstream why;
  if (r.bias.gyro.norm() > options.max_gyro_bias)
    why << "gyro bias " << r.bias.gyro.norm() << " rad/s (at most " << options.max_gyro_bias << ")";
  else if (r.bias.accel.norm() > options.max_accel_bias)
    why << "accelerometer bias " << r.bias.accel.norm() << " m/s^2 (at most " << options.max_accel_bias << ")";
  if (why.tellp() > 0) return why.str();
  if (const double median = median_of(r.link_rotation_chi2); !(median <= options.max_median_rotation_chi2))
    return "the gyro disagrees with the visual rotation (median rotation chi2 " + std::to_string(median) +
           " per link, at most " + std::to_string(options.max_median_rotation_chi2) + ")";
  if (const double median = median_of(r.link_chi2);
      solver.accel_bias_prior <= 1.0 && !(median <= options.max_median_link_chi2))
    return "the IMU disagrees with the visual motion (median inertial chi2 " + std::to_string(median) +
           " per link, at most " + std::to_string(options.max_median_link_chi2) + ")";
  const double turn_deg = gravity_turn_deg(r, current_gravity_w);
  if (refinement && turn_deg > options.max_refinement_turn_deg)
    return "it would turn the map's gravity by " + std::to_string(turn_deg) + " deg (at most " +
           std::to_string(options.max_refinement_turn_deg) + ")";
  return {};
}

// The change of the map's frame that points gravity along -z (R_w_g: the
// gravity frame in the map's), turning about the newest keyframe `p_pivot`
// (where it was before a rescale by `scale`), which stays where it is: the
// frame is free up to its yaw and origin, and a device tracked there keeps its
// position instead of moving by its distance from the origin times the turn
// (tenths of a degree at 10 m: centimetres at each refinement).
Pose3 gravity_alignment(const Eigen::Matrix3d& R_w_g, const Eigen::Vector3d& p_pivot, double scale) {
  const Eigen::Matrix3d R_new_old = R_w_g.transpose();
  return Pose3(Eigen::Quaterniond(R_new_old), p_pivot - R_new_old * (scale * p_pivot));
}

std::optional<Map::InertialState> estimate_and_apply(Map& map, const std::vector<std::shared_ptr<KeyFrame>>& chain,
                                                     const ImuBias& linearisation, Map::InertialState state,
                                                     const InertialInitializationOptions& options,
                                                     const InertialInitOptions& solver, Atlas* atlas,
                                                     const std::string& what, bool refinement) {
  // The map's gravity before this estimate (a refinement's turn is measured from it).
  const Eigen::Vector3d previous_gravity_w = refinement ? state.gravity_w : Eigen::Vector3d(0.0, 0.0, -1.0);
  std::vector<Pose3> poses;
  std::vector<Preintegration> increments;
  for (std::size_t k = 0; k < chain.size(); ++k) {
    poses.push_back(chain[k]->T_w_b());
    if (k > 0) increments.push_back(*chain[k]->inertial_link()->from_previous);
  }
  // One linearisation point for the window (the session preintegrates at the
  // map's estimate of the time).
  for (auto& pre : increments)
    if (!(pre.bias() == linearisation)) pre.reintegrate(linearisation);
  const InertialInitResult result = initialize_inertial(poses, increments, options.T_b_i, solver);
  const bool finite = std::all_of(result.velocities.begin(), result.velocities.end(),
                                  [](const Eigen::Vector3d& v) { return v.allFinite(); }) &&
                      result.bias.gyro.allFinite() && result.bias.accel.allFinite();
  const std::string refused = what + " of map " + std::to_string(map.id()) + " refused";
  const std::string after = refinement ? " (the map keeps its estimate)" : " (retried)";
  if (!finite || !result.gravity_w.allFinite() || result.final_cost > result.initial_cost) {
    log_warn(refused + ": no consistent solution" + after);
    return std::nullopt;
  }
  if (const std::string why = implausible(result, options, solver, refinement, previous_gravity_w); !why.empty()) {
    log_warn(refused + ": " + why + after);
    return std::nullopt;
  }
  // A monocular map is made metric: scaled by what the IMU says (its
  // velocities come out metric), before it is turned.
  const bool rescale = solver.estimate_scale && std::abs(result.scale - 1.0) > 1e-9;
  if (solver.estimate_scale && !(std::isfinite(result.scale) && result.scale > 0.0)) {
    log_warn(what + " of map " + std::to_string(map.id()) + " found no usable scale (retried)");
    return std::nullopt;
  }
  const std::size_t reintegrated = reintegrate_far_links(chain, result.bias, options.reintegrate_gyro_bias_change);
  // The initialisation turns the map so that gravity points along -z; a
  // refinement leaves the map's frame as it is (a device tracked there would
  // see its earlier poses turn about it) and keeps the gravity it found.
  state.gravity_w = refinement ? result.gravity_w : Eigen::Vector3d(0.0, 0.0, -solver.gravity);
  state.bias = result.bias;
  {
    // Sessions tracking in the map see it before or after, never half-turned.
    std::unique_lock<WriterPriorityMutex> whole;
    if (atlas) whole = atlas->lock_maps_exclusive();
    if (rescale) map.rescale(result.scale);
    for (std::size_t k = 0; k < chain.size() && k < result.velocities.size(); ++k) {
      const Eigen::Matrix3d R_w_i = (poses[k] * options.T_b_i).q.normalized().toRotationMatrix();
      chain[k]->set_imu_state(KeyFrame::ImuState{R_w_i.transpose() * result.velocities[k], result.bias});
    }
    const Eigen::Matrix3d turn = refinement ? Eigen::Matrix3d::Identity() : result.R_w_g;
    if (!refinement || rescale) map.change_frame(gravity_alignment(turn, poses.back().t, rescale ? result.scale : 1.0));
    map.set_inertial_state(state);
  }
  const double turn_deg = gravity_turn_deg(result, previous_gravity_w);
  std::ostringstream line;
  line << what << " of map " << map.id() << ": " << chain.size() << " keyframes over "
       << ns_to_s(chain.back()->timestamp_ns() - chain.front()->timestamp_ns()) << " s; gravity was ("
       << result.gravity_w.transpose() << ") m/s^2 in the map ("
       << (refinement ? "kept, the map's frame unchanged: " : "turned by ") << turn_deg
       << (refinement ? " deg from the map's estimate" : " deg to point it along -z") << "); gyro bias ("
       << result.bias.gyro.transpose() << ") rad/s, accelerometer bias (" << result.bias.accel.transpose()
       << ") m/s^2; " << result.iterations << " iterations; " << reintegrated
       << " links integrated again at the gyro bias found; chi2 per link median " << median_of(result.link_chi2)
       << " (rotation " << median_of(result.link_rotation_chi2) << ")"
       << ", max "
       << (result.link_chi2.empty() ? 0.0 : *std::max_element(result.link_chi2.begin(), result.link_chi2.end()));
  if (solver.estimate_scale) line << "; scale " << result.scale << " applied";
  log_info(line.str());
  return state;
}

// A single camera's map whose lengths are already metres (it was merged into a
// stereo or RGB-D map: measured depths) keeps them: its IMU estimate leaves
// the scale alone instead of rescaling the whole map.
InertialInitOptions solver_for(const Map& map, InertialInitOptions solver) {
  if (map.measured_depth()) solver.estimate_scale = false;
  return solver;
}

}  // namespace

std::optional<Map::InertialState> initialize_map_inertial(Map& map, const std::shared_ptr<KeyFrame>& newest,
                                                          const InertialInitializationOptions& options, Atlas* atlas) {
  if (!options.enabled || map.inertial_state() || !newest || newest->is_bad()) return std::nullopt;
  auto chain = inertial_chain(newest);
  // After the map's IMU was found to disagree: from the keyframes after that only.
  const TimestampNs cleared_at = map.inertial_cleared_at();
  std::erase_if(chain, [cleared_at](const auto& kf) { return kf->timestamp_ns() < cleared_at; });
  if (chain.size() < options.min_keyframes) return std::nullopt;
  const double span_s = ns_to_s(chain.back()->timestamp_ns() - chain.front()->timestamp_ns());
  if (span_s < options.after_s) return std::nullopt;
  Map::InertialState state;
  state.initialized_at_ns = newest->timestamp_ns();
  state.keyframes = chain.size();
  state.span_s = span_s;
  return estimate_and_apply(map, chain, chain[1]->inertial_link()->from_previous->bias(), state, options,
                            solver_for(map, options.solver), atlas, "inertial initialisation", false);
}

std::optional<Map::InertialState> refine_map_inertial(Map& map, const std::shared_ptr<KeyFrame>& newest,
                                                      const InertialInitializationOptions& options, Atlas* atlas) {
  const auto state = map.inertial_state();
  if (!options.enabled || !state || !newest || newest->is_bad() || state->refinements >= options.refinements.size())
    return std::nullopt;
  const InertialRefinement& step = options.refinements[state->refinements];
  if (ns_to_s(newest->timestamp_ns() - state->initialized_at_ns) < step.after_s) return std::nullopt;
  auto chain = inertial_chain(newest, options.refinement_max_keyframes);
  const TimestampNs cleared_at = map.inertial_cleared_at();  // the keyframes before an IMU reset are not used
  std::erase_if(chain, [cleared_at](const auto& kf) { return kf->timestamp_ns() < cleared_at; });
  Map::InertialState refined = *state;
  ++refined.refinements;  // tried once: a chain too short (a session that joined the map late) is not waited for
  const double span_s = chain.empty() ? 0.0 : ns_to_s(chain.back()->timestamp_ns() - chain.front()->timestamp_ns());
  // A chain much shorter than the one the map's gravity and scale came from (a
  // session that joined the map late, or a map merged in after a loss) would
  // turn and scale the whole map by what a few seconds saw: not tried.
  if (chain.size() < options.min_keyframes || span_s < options.refinement_min_span_fraction * state->span_s) {
    map.set_inertial_state(refined);
    return std::nullopt;
  }
  Map::InertialState estimate = refined;  // what the map holds when it is applied
  estimate.keyframes = chain.size();
  estimate.span_s = span_s;
  InertialInitOptions solver = solver_for(map, options.solver);
  solver.gyro_bias_prior = step.gyro_bias_prior;
  solver.accel_bias_prior = step.accel_bias_prior;
  std::string what = "inertial refinement " + std::to_string(refined.refinements);
  // A single camera's map is left as before (its refinements rescale it too): with
  // the bias held, monocular-inertial MH_03 ended worse in the one run measured.
  if (!solver.estimate_scale && solver.accel_bias_prior < options.held_accel_bias_prior) {
    std::vector<Eigen::Matrix3d> R_w_i;
    for (const auto& kf : chain) R_w_i.push_back((kf->T_w_b() * options.T_b_i).q.normalized().toRotationMatrix());
    const double turn_deg = turn_about_gravity_deg(R_w_i, state->gravity_w);
    if (turn_deg < options.min_turn_to_free_accel_bias_deg) {
      solver.accel_bias_prior = options.held_accel_bias_prior;
      std::ostringstream held;
      held << what << " (accelerometer bias held: the chain turned " << turn_deg << " deg about gravity, under "
           << options.min_turn_to_free_accel_bias_deg << ")";
      what = held.str();
    }
  }
  auto applied = estimate_and_apply(map, chain, state->bias, estimate, options, solver, atlas, what, true);
  if (!applied) map.set_inertial_state(refined);
  return applied;
}

}  // namespace orbatlas
