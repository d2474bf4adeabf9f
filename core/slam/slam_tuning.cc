#include "core/slam/slam_tuning.h"

#include <cmath>
#include <functional>
#include <limits>
#include <sstream>

#include "core/common/error.h"

namespace orbatlas {
namespace {

struct Binding {
  SlamTuningKey key;
  std::function<double(const SlamSystemOptions&)> get;
  std::function<void(SlamSystemOptions&, double)> set;
};

#define ORBATLAS_TUNING(KEY, MIN, MAX, INTEGER, MEANING, FIELD)                                           \
  Binding {                                                                                               \
    SlamTuningKey{KEY, MIN, MAX, INTEGER, MEANING},                                                       \
        [](const SlamSystemOptions& o) { return static_cast<double>(o.FIELD); },                          \
        [](SlamSystemOptions& o, double v) { o.FIELD = static_cast<std::decay_t<decltype(o.FIELD)>>(v); } \
  }

const std::vector<Binding>& bindings() {
  static const std::vector<Binding> all = {
      ORBATLAS_TUNING("Tracker.MinInitStereoPoints", 10, 100000, true, "stereo matches needed to start a map",
                      tracker.min_init_stereo_points),
      ORBATLAS_TUNING("Tracker.MinInliers", 5, 10000, true,
                      "map points a tracked frame needs after the local-map search", tracker.min_inliers),
      ORBATLAS_TUNING("Tracker.MinInliersAfterRecovery", 5, 10000, true,
                      "the same during the first second after a relocalisation", tracker.min_inliers_after_recovery),
      ORBATLAS_TUNING("Tracker.MinInliersInertial", 5, 10000, true,
                      "the same with the IMU (a frame predicted in an inertially initialised map)",
                      tracker.min_inliers_inertial),
      ORBATLAS_TUNING("Tracker.MinInliersInertialRecentlyLost", 5, 10000, true,
                      "the same while recently lost, when the IMU's prediction is searched from",
                      tracker.min_inliers_inertial_recently_lost),
      ORBATLAS_TUNING("Tracker.MaxFramesBetweenKeyframes", 1, 10000, true,
                      "a keyframe at least this often (default: the frame rate)", tracker.max_frames_between_keyframes),
      ORBATLAS_TUNING("Tracker.MaxKeyframeIntervalSeconds", 0, 3600, false,
                      "a keyframe at least this often while tracking holds (0: the sensor's, 0.5 s with an IMU, "
                      "0.25 s for a single camera with one, none without)",
                      tracker.max_keyframe_interval_s),
      ORBATLAS_TUNING("Tracker.RecentlyLostSeconds", 0, 3600, false,
                      "relocalisation is tried this long before a lost map is given up", tracker.recently_lost_s),
      ORBATLAS_TUNING("Tracker.MaxMappingWaitMs", 0, TrackerOptions::kLongestMappingWaitMs, false,
                      "the frame after a keyframe waits this long at most for local mapping to adjust it (0: never)",
                      tracker.max_mapping_wait_ms),
      ORBATLAS_TUNING("Tracker.OwnClosePoints", 0, 1, true,
                      "1: the keyframe decision counts as tracked only the close points the session's own keyframes "
                      "observe (maps several sessions map)",
                      tracker.own_close_points),
      ORBATLAS_TUNING(
          "Tracker.MaxLocalKeyframes", 5, 1000, true,
          "at most this many keyframes in the local map a frame is tracked in, those observing its points first",
          tracker.max_local_keyframes),
      ORBATLAS_TUNING("Tracker.MinKeyframesToKeepMap", 0, 1000, true,
                      "a map lost with fewer keyframes is given up at once", tracker.min_keyframes_to_keep_map),
      ORBATLAS_TUNING("Tracker.Relocalization", 0, 1, true, "1: a lost session relocalises in every map of the atlas",
                      relocalization),
      ORBATLAS_TUNING("Tracker.NewMapAfterFailedRelocalizations", 0, 10000, true,
                      "with live merging: frames of failed relocalisation before a new map starts",
                      new_map_after_failed_relocalizations),
      ORBATLAS_TUNING("LocalMapping.QueueCapacity", 1, 1000, true, "keyframes waiting for local mapping",
                      mapper.queue_capacity),
      ORBATLAS_TUNING("LocalMapping.TriangulationNeighbours", 1, 100, true,
                      "best covisible keyframes new points are triangulated with", mapper.triangulation_neighbours),
      ORBATLAS_TUNING("LocalMapping.FusionNeighbours", 1, 100, true, "keyframes a new keyframe's points are fused with",
                      mapper.fusion_neighbours),
      ORBATLAS_TUNING("LocalMapping.FusionRadius", 0.5, 20, false, "search radius of point fusion [pixels at level 0]",
                      mapper.fusion_radius),
      ORBATLAS_TUNING("LocalMapping.BundleAdjustment", 0, 1, true, "1: local bundle adjustment after each keyframe",
                      mapper.run_bundle_adjustment),
      Binding{SlamTuningKey{"LocalMapping.BundleAdjustmentCovisibles", 0, 1000, true,
                            "covisible keyframes adjusted with each new one, the best first (0: all, as ORB-SLAM)"},
              [](const SlamSystemOptions& o) {
                const std::size_t n = o.mapper.bundle_adjustment.max_covisibles;
                return n == std::numeric_limits<std::size_t>::max() ? 0.0 : static_cast<double>(n);
              },
              [](SlamSystemOptions& o, double v) {
                o.mapper.bundle_adjustment.max_covisibles =
                    v == 0.0 ? std::numeric_limits<std::size_t>::max() : static_cast<std::size_t>(v);
              }},
      ORBATLAS_TUNING("LocalMapping.Culling", 0, 1, true, "1: redundant keyframes are culled", mapper.run_culling),
      ORBATLAS_TUNING("LocalMapping.InertialWindowKeyframes", 2, 100, true,
                      "visual-inertial local BA: keyframes of the inertial chain with velocity and biases",
                      mapper.inertial_window_keyframes),
      ORBATLAS_TUNING("LocalMapping.InertialCovisibleKeyframes", 0, 1000, true,
                      "visual-inertial local BA: best covisible keyframes optimised beside the chain's",
                      mapper.inertial_covisible_keyframes),
      ORBATLAS_TUNING("LocalMapping.ImuScaleSigma", 0, 0.05, false,
                      "visual-inertial local BA: prior sigma of the IMU's scale factors per axis about the map's "
                      "estimate (0: the factors are not estimated; docs/inertial.md)",
                      mapper.imu_scale_sigma),
      ORBATLAS_TUNING("LocalMapping.InertialReintegrateGyroBiasChange", 0, 10, false,
                      "links linearised at a gyro bias this far [rad/s] from the one an initialisation or refinement "
                      "finds are integrated again (10: never)",
                      mapper.inertial.reintegrate_gyro_bias_change),
      ORBATLAS_TUNING("LocalMapping.InertialMaxMedianRotationChi2", 1, 1e6, false,
                      "an inertial initialisation or refinement is kept only when its links' median rotation chi2 "
                      "(3 degrees of freedom) is at most this",
                      mapper.inertial.max_median_rotation_chi2),
      ORBATLAS_TUNING("LocalMapping.InertialMaxMedianChi2", 1, 1e6, false,
                      "a refinement with the accelerometer bias free is kept only when its links' median inertial "
                      "chi2 (9 degrees of freedom) is at most this",
                      mapper.inertial.max_median_link_chi2),
      ORBATLAS_TUNING("LocalMapping.InertialConsistencyMaxChi2", 1, 1e9, false,
                      "a map whose last 5 visual-inertial local BAs end with a median inertial chi2 (9 degrees of "
                      "freedom) above this goes visual-only until it is initialised again (twice; then for good)",
                      mapper.inertial_consistency.max_median_chi2),
      ORBATLAS_TUNING("LocalMapping.InertialRefinementMinSpan", 0, 1, false,
                      "an inertial refinement runs on a chain spanning at least this fraction of the window the "
                      "map's estimate came from (0: always)",
                      mapper.inertial.refinement_min_span_fraction),
      ORBATLAS_TUNING("LocalMapping.InertialRefinementMinTurnDeg", 0, 360, false,
                      "a refinement of a stereo or RGB-D map frees the accelerometer bias only once its chain has "
                      "turned about gravity by at least this many degrees (until then the bias is held under the "
                      "5-s refinement's prior)",
                      mapper.inertial.min_turn_to_free_accel_bias_deg),
      ORBATLAS_TUNING("LoopClosing.Enabled", 0, 1, true, "1: place recognition, loop correction, global BA",
                      loop_closing),
      ORBATLAS_TUNING("LoopClosing.QueueCapacity", 1, 10000, true,
                      "keyframes waiting for place recognition (more are skipped)", loop.queue_capacity),
      ORBATLAS_TUNING("LoopClosing.GlobalBundleAdjustment", 0, 1, true, "1: a global BA after each loop correction",
                      loop.global_bundle_adjustment),
      ORBATLAS_TUNING("LoopClosing.LiveMerging", 0, 1, true,
                      "1: a session's map is merged into another map of the atlas while it runs", live_merging),
      ORBATLAS_TUNING("LoopClosing.SharedMapRefinementGrowth", 0, 100, false,
                      "a map several sessions map at once gets a global BA each time its keyframes grew by this "
                      "fraction since its last one (0: never)",
                      loop.shared_map_refinement_growth),
      ORBATLAS_TUNING("LoopClosing.StreamEndRefinementGrowth", 0, 100, false,
                      "when a session ends in a map other sessions mapped too and its keyframes grew by this fraction "
                      "since its last global BA, one more runs (the server's --finish-refinement-wait; 0: never)",
                      loop.stream_end_refinement_growth),
      ORBATLAS_TUNING("LoopClosing.SettledInertialRefinements", 0, 1000, true,
                      "a single camera's inertial map is merged as a similarity (taking the target's scale) until "
                      "this many inertial refinements",
                      loop.settled_inertial_refinements),
      ORBATLAS_TUNING("LoopClosing.FinalBaForImuScale", 0, 1, true,
                      "1: a single camera with an IMU ends with a full visual-inertial global BA (its map's scale from "
                      "every inertial term; a server session at its finish)",
                      final_ba_for_imu_scale),
  };
  return all;
}

#undef ORBATLAS_TUNING

std::string text(double v) {
  std::ostringstream out;
  out << v;
  return out.str();
}

std::string known_keys() {
  std::string out;
  for (const Binding& b : bindings()) out += (out.empty() ? "" : ", ") + b.key.key;
  return out;
}

const Binding& binding(const std::string& key) {
  for (const Binding& b : bindings())
    if (b.key.key == key) return b;
  throw DataError("settings: unknown key 'Orbatlas." + key + "' (known: " + known_keys() + ")");
}

bool passes_check(const SlamSystemOptions& options) {
  try {
    options.check();
    return true;
  } catch (const Error&) {
    return false;
  }
}

// The keys to blame for options that fail their check: the first key that alone
// makes `options` fail, else all of them (only together out of range).
std::string blamed_keys(const std::map<std::string, double>& tuning, const SlamSystemOptions& options) {
  for (const auto& [key, value] : tuning) {
    SlamSystemOptions one = options;
    binding(key).set(one, value);
    if (!passes_check(one)) return "'Orbatlas." + key + "' = " + text(value);
  }
  std::string all;
  for (const auto& [key, value] : tuning)
    all += (all.empty() ? "" : ", ") + ("'Orbatlas." + key + "' = " + text(value));
  return all;
}

}  // namespace

const std::vector<SlamTuningKey>& slam_tuning_keys() {
  static const std::vector<SlamTuningKey> keys = [] {
    std::vector<SlamTuningKey> out;
    for (const Binding& b : bindings()) out.push_back(b.key);
    return out;
  }();
  return keys;
}

void apply_slam_tuning(const std::map<std::string, double>& tuning, SlamSystemOptions& options) {
  SlamSystemOptions changed = options;
  for (const auto& [key, value] : tuning) {
    const Binding& found = binding(key);
    const SlamTuningKey& k = found.key;
    if (!(value >= k.min && value <= k.max))
      throw DataError("settings: 'Orbatlas." + key + "' must be in " + text(k.min) + " .. " + text(k.max) + ", got " +
                      text(value));
    if (k.integer && value != std::floor(value))
      throw DataError("settings: 'Orbatlas." + key + "' must be a whole number, got " + text(value));
    found.set(changed, value);
  }
  // Each key is in its range; the options as a whole must pass their check too.
  try {
    changed.check();
  } catch (const Error& e) {
    if (!passes_check(options)) throw;  // out of range before any key was applied: not the settings' fault
    throw DataError("settings: " + blamed_keys(tuning, options) + " cannot be used here: " + e.what());
  }
  options = std::move(changed);
}

std::map<std::string, double> slam_tuning_values(const SlamSystemOptions& options) {
  std::map<std::string, double> out;
  for (const Binding& b : bindings()) out[b.key.key] = b.get(options);
  return out;
}

}  // namespace orbatlas
