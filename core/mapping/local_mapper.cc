#include "core/mapping/local_mapper.h"

#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <unordered_set>

#include "core/common/error.h"
#include "core/common/stopwatch.h"
#include "core/common/log.h"
#include "core/map/map_point_update.h"
#include "core/optimization/apply_global_adjustment.h"
#include "core/mapping/fusion.h"
#include "core/mapping/triangulation.h"

namespace orbatlas {
namespace {

// ORB-SLAM's observation count: a stereo observation counts twice.
int weighted_observations(const MapPoint& point) {
  int n = 0;
  for (const auto& obs : point.observations()) {
    const auto kf = obs.kf.lock();
    if (!kf) continue;
    n += kf->u_right(obs.slot) >= 0.0f ? 2 : 1;
  }
  return n;
}

}  // namespace

void LocalMapperOptions::check() const {
  ORBATLAS_CHECK(queue_capacity > 0, "local mapping: queue_capacity must be > 0, not " << queue_capacity);
  ORBATLAS_CHECK(worker_nice >= 0 && worker_nice <= 19,
                 "local mapping: worker_nice must be in 0..19, not " << worker_nice);
  ORBATLAS_CHECK(std::isfinite(fusion_radius) && fusion_radius >= 0.0f,
                 "local mapping: fusion_radius must be a finite value >= 0, not " << fusion_radius);
  culling.check();
  bundle_adjustment.check();
  inertial.check();
  inertial_consistency.check();
  ORBATLAS_CHECK(std::isfinite(imu_scale_sigma) && imu_scale_sigma >= 0.0 && imu_scale_sigma < 0.05,
                 "local mapping: imu_scale_sigma must be in [0, 0.05), not " << imu_scale_sigma);
  ORBATLAS_CHECK(inertial_window_keyframes >= 2,
                 "local mapping: inertial_window_keyframes must be >= 2, not " << inertial_window_keyframes);
  ORBATLAS_CHECK(full_inertial_ba_iterations >= 0,
                 "local mapping: full_inertial_ba_iterations must be >= 0, not " << full_inertial_ba_iterations);
}

LocalMapper::LocalMapper(Atlas& atlas, FrameCamera cam, LocalMapperOptions options, KeyframeIndex* index,
                         std::shared_ptr<LocalMapperStatsBoard> board)
    : atlas_(atlas),
      index_(index),
      cam_(std::move(cam)),
      options_((options.check(), std::move(options))),
      board_(board ? std::move(board) : std::make_shared<LocalMapperStatsBoard>()),
      worker_(
          QueueWorkerOptions::own_thread("local mapping", options_.queue_capacity, 20, options_.worker_nice),
          [this](Item& item) { run_one(item); },
          [](const Item& item) { return "keyframe " + std::to_string(item.keyframe->id()); }) {
  ORBATLAS_CHECK(cam_.camera != nullptr, "local mapper needs a camera");
}

LocalMapper::~LocalMapper() {
  try {
    finish();
  } catch (const std::exception& e) {
    log_warn(std::string("local mapping stopped with an error: ") + e.what());
  }
}

bool LocalMapper::insert(std::shared_ptr<KeyFrame> keyframe, std::uint64_t source) {
  handed_in(source);
  if (worker_.push(Item{std::move(keyframe), source})) return true;
  adjusted(source);
  processed(source);
  return false;
}

void LocalMapper::handed_in(std::uint64_t source) {
  std::lock_guard lock(pending_mutex_);
  ++pending_[source];
  ++unadjusted_[source];
}

void LocalMapper::adjusted(std::uint64_t source) {
  {
    std::lock_guard lock(pending_mutex_);
    if (--unadjusted_[source] == 0) unadjusted_.erase(source);
  }
  adjusted_cv_.notify_all();
}

void LocalMapper::processed(std::uint64_t source) {
  std::lock_guard lock(pending_mutex_);
  if (--pending_[source] == 0) pending_.erase(source);
}

bool LocalMapper::wait_until_adjusted(std::uint64_t source, std::chrono::milliseconds at_most) const {
  std::unique_lock lock(pending_mutex_);
  return adjusted_cv_.wait_for(lock, at_most, [&] { return !unadjusted_.contains(source); });
}

bool LocalMapper::idle(std::uint64_t source) const {
  std::lock_guard lock(pending_mutex_);
  return !pending_.contains(source);
}

void LocalMapper::interrupt_optimization(std::uint64_t source) {
  if (processing_source_.load() == source) abort_ba_.store(true);
}

bool LocalMapper::hurry(std::uint64_t source) const {
  if (2 * worker_.queued() >= options_.queue_capacity) return true;
  std::lock_guard lock(pending_mutex_);
  const auto it = pending_.find(source);
  return it != pending_.end() && it->second > 1;  // the one being processed counts itself
}

LocalMapperStats LocalMapper::stats() const {
  LocalMapperStats out;
  {
    std::lock_guard lock(board_->mutex);
    out = board_->stats;
  }
  out.errors = worker_.errors();
  return out;
}

void LocalMapper::set_processed_listener(std::function<void(const std::shared_ptr<KeyFrame>&)> listener) {
  processed_listener_ = std::move(listener);
}

void LocalMapper::run_one(Item& item) {
  // A failure leaves the keyframe as far as it was processed (every edit is a
  // whole step of the map model); the worker counts it and goes on.
  struct Done {
    LocalMapper& mapper;
    std::uint64_t source;
    ~Done() {
      if (!mapper.counted_adjusted_) mapper.adjusted(source);  // it ended early (a bad keyframe, an error)
      mapper.processed(source);
    }
  } done{*this, item.source};
  processing_source_.store(item.source);
  abort_ba_.store(false);
  counted_adjusted_ = false;
  process(item.keyframe, item.source);
  if (processed_listener_ && !item.keyframe->is_bad()) processed_listener_(item.keyframe);
}

void LocalMapper::process(const std::shared_ptr<KeyFrame>& keyframe, std::uint64_t source) {
  const auto start = std::chrono::steady_clock::now();
  const auto map = atlas_.map(keyframe->map_id());
  if (!map || keyframe->is_bad()) return;
  if (!origins_.contains(map->id())) origins_[map->id()] = spanning_tree_root(*map, *keyframe);

  complete_keyframe(keyframe);
  if (index_) index_->add(keyframe);
  cull_recent_points(*map);
  triangulate(*map, keyframe, source);
  if (!hurry(source)) fuse_with_neighbours(*map, keyframe);

  double ba_ms = -1.0;
  std::size_t ba_window = 0, ba_fixed = 0;
  KeyframeCullingResult culling;
  bool culling_ran = false;
  bool interrupted = false;
  std::size_t inertial_bas = 0, inertial_refinements = 0, inertial_resets = 0, inertial_given_up = 0;
  std::optional<double> inertial_chi2_median;
  std::optional<GlobalBundleAdjustmentResult> full_ba;
  if (!hurry(source) && !abort_ba_.load()) {
    if (options_.run_bundle_adjustment && map->keyframe_count() > 2) {
      LocalBundleAdjustmentOptions ba = options_.bundle_adjustment;
      ba.origin = origins_.at(map->id());
      ba.level_sigma2 = cam_.pyramid.level_sigma2();
      const auto inertial_state = options_.inertial.enabled ? map->inertial_state() : std::nullopt;
      if (inertial_state && options_.inertial_bundle_adjustment)
        ba.inertial = InertialWindowOptions{.T_b_i = options_.inertial.T_b_i,
                                            .gravity_w = inertial_state->gravity_w,
                                            .map_bias = inertial_state->bias,
                                            .temporal_keyframes = options_.inertial_window_keyframes,
                                            .scale = inertial_state->scale,
                                            .scale_sigma = options_.imu_scale_sigma};
      if (ba.inertial) ba.max_covisibles = std::min(ba.max_covisibles, options_.inertial_covisible_keyframes);
      const auto stats = local_bundle_adjustment(*map, keyframe, *cam_.camera, cam_.bf, ba, &abort_ba_);
      ba_ms = stats.time_ms;
      ba_window = stats.window_keyframes;
      ba_fixed = stats.fixed_keyframes;
      interrupted = stats.stopped;
      if (stats.inertial_edges > 0) {
        ++inertial_bas;
        inertial_chi2_median = stats.inertial_chi2_median;
        const auto verdict = consistency_.add(map->id(), stats.inertial_chi2_median);
        if (verdict != InertialConsistency::Verdict::kKeep) {
          map->clear_inertial_state(keyframe->timestamp_ns());
          scale_filter_.forget(map->id());
          // What the IMU bent, a visual global BA straightens (the loop closer's, in the background).
          if (options_.defer_full_inertial_ba) map->request_inertial_adjustment();
          const bool for_good = verdict == InertialConsistency::Verdict::kGiveUp;
          ++(for_good ? inertial_given_up : inertial_resets);
          log_warn(
              "map " + std::to_string(map->id()) + ": its IMU disagrees with vision (median inertial chi2 over " +
              std::to_string(options_.inertial_consistency.max_median_chi2).substr(0, 5) +
              " in the last local BAs, 9 dof; " + std::to_string(stats.inertial_chi2_median).substr(0, 7) +
              " in the latest): " +
              (for_good ? "the map stays visual-only" : "visual-only until its inertial initialisation agrees again"));
        } else if (const auto imu = keyframe->imu_state(); imu && inertial_state) {
          // Tracking predicts with the newest keyframe's biases; the window's
          // scale correction joins the map's estimate.
          Map::InertialState refined = *inertial_state;
          refined.bias = imu->bias;
          if (options_.imu_scale_sigma > 0.0)
            refined.scale = scale_filter_.add(map->id(), refined.scale, stats.imu_scale, stats.imu_scale_information);
          map->set_inertial_state(refined);
        }
      }
    }
    if (options_.run_culling) {
      culling = cull_redundant_keyframes(*map, *keyframe, origins_.at(map->id()), options_.culling);
      culling_ran = true;
      if (index_)
        for (const KeyframeId id : culling.culled) index_->erase(id);
    }
  }
  adjusted(source);  // tracking may go on (Tracker::wait_for_mapping)
  counted_adjusted_ = true;
  ++sequence_;
  if (options_.inertial.enabled) {
    const bool initialised = map->inertial_state().has_value();
    try {
      std::optional<Map::InertialState> set;
      if (initialised) {
        set = refine_map_inertial(*map, keyframe, options_.inertial, &atlas_);
        if (set) ++inertial_refinements;
      } else if (!consistency_.given_up(map->id())) {
        set = initialize_map_inertial(*map, keyframe, options_.inertial, &atlas_);
      }
      if (set && options_.full_inertial_ba_iterations > 0) {
        if (options_.defer_full_inertial_ba) {
          map->request_inertial_adjustment();
        } else {
          full_ba = full_inertial_ba(*map, keyframe, *set);
        }
      }
    } catch (const Error& e) {
      log_warn(std::string("inertial ") + (initialised ? "refinement" : "initialisation") + " of map " +
               std::to_string(map->id()) + " failed: " + e.what() + (initialised ? "" : " (retried)"));
    }
  }

  std::lock_guard lock(board_->mutex);
  ++board_->stats.keyframes;
  board_->stats.keyframe_ms.add(ms_since(start));
  if (ba_ms >= 0.0) {
    board_->stats.bundle_adjustment_ms.add(ba_ms);
    board_->stats.bundle_adjustment_window.add(static_cast<double>(ba_window));
    board_->stats.bundle_adjustment_fixed.add(static_cast<double>(ba_fixed));
  }
  if (interrupted) ++board_->stats.bundle_adjustments_interrupted;
  board_->stats.inertial_bundle_adjustments += inertial_bas;
  if (inertial_chi2_median) board_->stats.inertial_chi2_median.add(*inertial_chi2_median);
  board_->stats.inertial_refinements += inertial_refinements;
  board_->stats.inertial_resets += inertial_resets;
  board_->stats.inertial_given_up += inertial_given_up;
  if (full_ba && !full_ba->stopped) {
    ++board_->stats.full_inertial_bundle_adjustments;
    board_->stats.full_inertial_ba_ms.add(full_ba->time_ms);
  }
  if (culling_ran) {
    const bool scan = options_.culling.scheme == CullingScheme::kScan || options_.culling.compare_schemes;
    const bool incremental = options_.culling.scheme == CullingScheme::kIncremental || options_.culling.compare_schemes;
    if (scan) board_->stats.culling_scan_ms.add(culling.scan_us * 1e-3);
    if (incremental) board_->stats.culling_incremental_ms.add(culling.incremental_us * 1e-3);
    board_->stats.culling_candidates += static_cast<std::size_t>(culling.candidates);
    board_->stats.culling_disagreements += static_cast<std::size_t>(culling.disagreements);
    board_->stats.culled_keyframes += culling.culled.size();
    for (const KeyframeId id : culling.culled)
      board_->stats.culled_keyframes_digest = (board_->stats.culled_keyframes_digest ^ id) * 1099511628211ULL;
  }
}

GlobalBundleAdjustmentResult LocalMapper::full_inertial_ba(Map& map, const std::shared_ptr<KeyFrame>& keyframe,
                                                           const Map::InertialState& state) {
  GlobalBundleAdjustmentOptions ba;
  ba.iterations = options_.full_inertial_ba_iterations;
  ba.level_sigma2 = cam_.pyramid.level_sigma2();
  ba.origin = origins_.count(map.id()) ? std::optional<KeyframeId>(origins_.at(map.id())) : std::nullopt;
  ba.inertial =
      GlobalBundleAdjustmentOptions::Inertial{options_.inertial.T_b_i, options_.inertial.refinement_max_keyframes};
  // ORB-SLAM3's FullInertialBA. Not interrupted by new keyframes (they wait):
  // the map's states were just replaced and local BA would start from them
  // half-solved. Keyframes and points tracking made meanwhile follow their
  // parents' correction; sessions tracking in the map see it before or after.
  const auto result = global_bundle_adjustment(map, *cam_.camera, cam_.bf, ba);
  {
    const auto whole = atlas_.lock_maps_exclusive();
    apply_global_adjustment(map, result, cam_.pyramid);
  }
  std::ostringstream line;
  line << "full visual-inertial BA of map " << map.id() << ": " << result.keyframes << " keyframes ("
       << result.inertial_keyframes << " with IMU states), " << result.points << " points, " << result.iterations
       << " iterations, " << result.time_ms << " ms; inertial chi2 max " << result.inertial_chi2_max;
  log_info(line.str());
  // Tracking predicts with the newest keyframe's biases.
  if (const auto imu = keyframe->imu_state()) {
    Map::InertialState next = state;
    next.bias = imu->bias;
    map.set_inertial_state(next);
  }
  return result;
}

KeyframeId LocalMapper::spanning_tree_root(const Map& map, const KeyFrame& keyframe) {
  // A new map: its first keyframe. A map this session entered (a stored map,
  // or one its own map was merged into): the root of the map's spanning tree,
  // reached from its oldest keyframe (which local mapping has processed).
  const auto keyframes = map.keyframes();  // sorted by id
  if (keyframes.empty() || keyframes.front()->id() >= keyframe.id()) return keyframe.id();
  auto node = keyframes.front();
  std::unordered_set<KeyframeId> seen{node->id()};
  while (auto parent = node->parent()) {
    if (!seen.insert(parent->id()).second) break;  // a cycle would be a bug elsewhere; do not loop
    node = std::move(parent);
  }
  return node->id();
}

void LocalMapper::complete_keyframe(const std::shared_ptr<KeyFrame>& keyframe) {
  for (const auto& mp : keyframe->map_points()) {
    if (mp->is_bad()) continue;
    update_map_point(*mp, cam_.pyramid);
    if (mp->observation_count() == 1 && mp->reference_keyframe_id() == keyframe->id())
      recent_.push_back({mp, sequence_});
  }
  keyframe->update_connections();
  if (!keyframe->parent() && keyframe->id() != origins_.at(keyframe->map_id())) {
    // The best covisible keyframe that is older: tracking adds a new keyframe's
    // observations before local mapping processes it, so a newer, unprocessed
    // keyframe can already be the best covisible, and taking it could close a
    // cycle in the spanning tree (it would pick this one as its parent).
    for (const auto& candidate : keyframe->best_covisibles(std::numeric_limits<std::size_t>::max())) {
      if (candidate->id() < keyframe->id()) {
        keyframe->set_parent(candidate);
        break;
      }
    }
  }
}

void LocalMapper::cull_recent_points(Map& map) {
  std::size_t culled = 0;
  std::vector<RecentPoint> kept;
  kept.reserve(recent_.size());
  for (auto& entry : recent_) {
    const auto mp = entry.point.lock();
    if (!mp || mp->is_bad()) continue;
    const std::size_t age = sequence_ - entry.created_at;
    // ORB-SLAM: seen from at most 3 (stereo counting twice), or 2 for a single camera.
    const int min_observations = cam_.bf > 0.0 ? 3 : 2;
    if (mp->found_ratio() < 0.25 || (age >= 2 && weighted_observations(*mp) <= min_observations)) {
      if (map.cull_map_point(mp->id())) ++culled;
    } else if (age < 3) {
      kept.push_back(std::move(entry));
    }
  }
  recent_ = std::move(kept);
  std::lock_guard lock(board_->mutex);
  board_->stats.recent_points_culled += culled;
}

void LocalMapper::triangulate(Map& map, const std::shared_ptr<KeyFrame>& keyframe, std::uint64_t source) {
  std::vector<std::shared_ptr<MapPoint>> created;
  std::size_t n = 0;
  for (const auto& neighbour : keyframe->best_covisibles(options_.triangulation_neighbours)) {
    if (n++ > 0 && hurry(source)) break;  // the session's next keyframe is waiting: tracking needs us
    triangulate_pair(map, keyframe, neighbour, cam_, &created);
  }
  for (auto& mp : created) recent_.push_back({mp, sequence_});
  std::lock_guard lock(board_->mutex);
  board_->stats.points_triangulated += created.size();
}

void LocalMapper::fuse_with_neighbours(Map& map, const std::shared_ptr<KeyFrame>& keyframe) {
  std::vector<std::shared_ptr<KeyFrame>> targets;
  std::unordered_set<KeyframeId> in_targets{keyframe->id()};
  for (auto& kf : keyframe->best_covisibles(options_.fusion_neighbours))
    if (in_targets.insert(kf->id()).second) targets.push_back(std::move(kf));
  const std::size_t first_ring = targets.size();
  for (std::size_t i = 0; i < first_ring; ++i)
    for (auto& kf : targets[i]->best_covisibles(options_.fusion_second_neighbours))
      if (in_targets.insert(kf->id()).second) targets.push_back(std::move(kf));

  FusionStats total;
  const auto own = keyframe->map_points();
  for (const auto& target : targets) {
    const FusionStats s = fuse_into_keyframe(map, target, own, cam_, options_.fusion_radius);
    total.added += s.added;
    total.merged += s.merged;
  }
  std::vector<std::shared_ptr<MapPoint>> theirs;
  std::unordered_set<MapPointId> seen;
  for (const auto& target : targets)
    for (auto& mp : target->map_points())
      if (!mp->is_bad() && seen.insert(mp->id()).second) theirs.push_back(std::move(mp));
  const FusionStats s = fuse_into_keyframe(map, keyframe, theirs, cam_, options_.fusion_radius);
  total.added += s.added;
  total.merged += s.merged;

  for (const auto& mp : keyframe->map_points())
    if (!mp->is_bad()) update_map_point(*mp, cam_.pyramid);
  keyframe->update_connections();

  std::lock_guard lock(board_->mutex);
  board_->stats.points_fused += static_cast<std::size_t>(total.merged);
  board_->stats.observations_fused += static_cast<std::size_t>(total.added);
}

}  // namespace orbatlas
