#include "core/slam/slam_system.h"

#include <chrono>
#include <cmath>
#include <set>
#include <sstream>

#include "core/common/error.h"
#include "core/common/log.h"
#include "core/imu/white_noise_estimate.h"
#include "core/optimization/apply_global_adjustment.h"
#include "core/relocalization/index_relocalizer.h"
#include "core/slam/slam_tuning.h"

namespace orbatlas {
void SlamSystemOptions::check() const {
  ORBATLAS_CHECK(
      new_map_after_failed_relocalizations >= 0,
      "slam: new_map_after_failed_relocalizations must be >= 0, not " << new_map_after_failed_relocalizations);
  // The tracker refuses to localise without a relocaliser.
  ORBATLAS_CHECK(relocalization || !tracker.localization_only,
                 "slam: relocalization must be on when tracker.localization_only is set");
  ORBATLAS_CHECK(
      std::isfinite(shared_map_finish_wait_s) && shared_map_finish_wait_s >= 0.0 && shared_map_finish_wait_s <= 3600.0,
      "slam: shared_map_finish_wait_s must be in 0..3600, not " << shared_map_finish_wait_s);
  ORBATLAS_CHECK(std::isfinite(max_maps_wait_ms) && max_maps_wait_ms >= 0.0 && max_maps_wait_ms <= 10000.0,
                 "slam: max_maps_wait_ms must be in 0..10000, not " << max_maps_wait_ms);
  tracker.check();
  inertial_tracking.check();
  imu_time_offset.check();
  imu_input.check();
  mapper.check();
  loop.check();
  final_ba.check();
}

SlamSystem::SlamSystem(Atlas& atlas, const SlamSettings& settings, const Vocabulary& vocabulary,
                       SlamSystemOptions options, SessionWiring wiring)
    : atlas_(atlas),
      options_(std::move(options)),
      frontend_(make_frame_frontend(settings, options_.parallel_stereo_frontend)),
      rgbd_(settings.is_rgbd()),
      monocular_(frontend_->baseline() <= 0.0),
      time_offset_(options_.imu_time_offset) {
  cam_ = frontend_->frame_camera();
  frontend_->warm_up();  // the session's first frame costs what the others do
  options_.tracker.th_depth_m = settings.stereo_th_depth * frontend_->baseline();
  options_.tracker.max_frames_between_keyframes = std::max(1, static_cast<int>(std::lround(settings.fps)));
  if (monocular_) {
    // ORB-SLAM's single-camera rules: new points come from triangulation
    // only, so with more neighbours; loops and merges of a map without
    // metric scale are similarities (Sim(3)).
    options_.mapper.triangulation_neighbours = 20;
    options_.mapper.fusion_neighbours = 20;
    options_.loop.monocular = true;
  }
  if (!settings.orbatlas.empty()) {  // the settings' Orbatlas.* keys win over what is derived above
    apply_slam_tuning(settings.orbatlas, options_);
    const auto values = slam_tuning_values(options_);
    std::string set;
    for (const auto& [key, _] : settings.orbatlas) {
      std::ostringstream value;
      value << values.at(key);
      set += " Orbatlas." + key + "=" + value.str();
    }
    log_info("settings:" + set);
  }
  // A single camera's body is the camera (below): its IMU is placed in it.
  const Pose3 T_b_i =
      settings.imu ? (monocular_ ? frontend_->calibration().T_b_c.inverse() * settings.imu->T_b_i : settings.imu->T_b_i)
                   : Pose3();
  T_b_i_ = T_b_i;
  if (options_.inertial && settings.imu && !options_.tracker.localization_only) {
    imu_noise_ = ImuNoise::from(*settings.imu);
    ImuInputCheckOptions input = options_.imu_input;
    input.rate_hz = settings.imu->rate_hz;
    input.gyro_range = settings.imu->gyro_range;
    input.accel_range = settings.imu->accel_range;
    imu_input_ = std::make_unique<ImuInputCheck>(input);
    imu_input_->set_warning_sink([](const std::string& w) { log_warn(w); });
    options_.mapper.inertial.enabled = true;
    options_.mapper.inertial.T_b_i = T_b_i;
    // A single camera's map gets its metric scale from the IMU (ORB-SLAM3's
    // inertial-only estimate with the scale free), at the initialisation and
    // at each refinement.
    options_.mapper.inertial.solver.estimate_scale = monocular_;
    // ORB-SLAM3's first monocular-inertial estimate holds the accelerometer
    // bias at zero (prior 1e10): over 2 s it cannot be told from the scale.
    if (monocular_) options_.mapper.inertial.solver.accel_bias_prior = 1e10;
    // The global BAs (after a loop, --final-ba) of an initialised map keep its IMU terms.
    const GlobalBundleAdjustmentOptions::Inertial global_inertial{
        .T_b_i = T_b_i, .max_chain_keyframes = options_.mapper.inertial.refinement_max_keyframes};
    options_.loop.global.inertial = global_inertial;
    options_.final_ba.inertial = global_inertial;
    if (monocular_ && options_.final_ba_for_imu_scale) {
      options_.final_global_ba = true;            // offline, with mapping of its own
      options_.loop.stream_end_imu_scale = true;  // the server's shared mapping, at the session's end
    }
    // ORB-SLAM3's inertial keyframe rules: one at least every 0.5 s, and
    // culling keeps the joined increments short (0.5 s before the map's
    // initialisation, 3 s after).
    // A single camera (ORB-SLAM3's monocular-inertial rules): one keyframe
    // at least every 0.25 s, and ten of them before the initialisation (its
    // scale comes from them: with five at 0.5 s it was 20 % off on MH_01).
    if (options_.tracker.max_keyframe_interval_s == 0.0)
      options_.tracker.max_keyframe_interval_s = monocular_ ? 0.25 : 0.5;
    if (monocular_)
      options_.mapper.inertial.min_keyframes = std::max<std::size_t>(options_.mapper.inertial.min_keyframes, 10);
    if (options_.mapper.culling.max_inertial_span_s == 0.0) options_.mapper.culling.max_inertial_span_s = 0.5;
    if (options_.mapper.culling.max_inertial_span_initialized_s == 0.0)
      options_.mapper.culling.max_inertial_span_initialized_s = 3.0;
  }
  options_.check();
  if (!monocular_) {
    // A metric session (stereo, RGB-D) neither enters nor merges into a map of
    // free scale (a monocular one): its points would disagree in scale.
    const auto metric = [&atlas = atlas_](MapId id) {
      const auto map = atlas.map(id);
      return map && map->metric_scale();
    };
    const auto only_metric = [metric](std::function<bool(MapId)> allowed) {
      return std::function<bool(MapId)>(
          [metric, allowed = std::move(allowed)](MapId id) { return metric(id) && (!allowed || allowed(id)); });
    };
    wiring.may_enter_map = only_metric(std::move(wiring.may_enter_map));
    wiring.may_merge_into = only_metric(std::move(wiring.may_merge_into));
  }
  // A single camera's map has no metric scale, so the body is the camera
  // itself (a lever arm in metres would not fit the map's units): the poses
  // reported are the camera's.
  const Pose3 T_b_c = monocular_ ? Pose3() : frontend_->calibration().T_b_c;
  if (options_.relocalization)
    relocalizer_ =
        std::make_unique<IndexRelocalizer>(vocabulary, atlas_.keyframe_index(), cam_, T_b_c, wiring.may_enter_map);
  if (options_.tracker.localization_only) {
    sink_ = std::make_unique<NoKeyframes>();
  } else {
    if (options_.live_merging && options_.loop_closing && options_.relocalization &&
        options_.tracker.new_map_after_failed_relocalizations == 0)
      options_.tracker.new_map_after_failed_relocalizations = options_.new_map_after_failed_relocalizations;
    MappingWorkersOptions mapping{
        .mapper = options_.mapper, .loop_closing = options_.loop_closing, .loop = options_.loop};
    mapping.loop.live_merging = mapping.loop.live_merging || options_.live_merging;
    if (wiring.mapping) mapping_ = wiring.mapping(cam_, mapping);
    if (!mapping_) {
      own_mapping_ = true;
      mapping_ = std::make_shared<MappingWorkers>(atlas_, cam_, std::move(mapping),
                                                  LoopCloserWiring{.shared_worker = wiring.loop_worker,
                                                                   .may_merge_into = wiring.may_merge_into,
                                                                   .hold_map = wiring.hold_map,
                                                                   .on_merged = wiring.on_merged});
    }
    sink_ = mapping_->attach();
  }
  tracker_ = std::make_unique<Tracker>(atlas_, vocabulary, *sink_, cam_, T_b_c, options_.tracker, relocalizer_.get());
  if (imu_noise_) {
    inertial_tracking_ =
        std::make_unique<InertialTracking>(imu_, *imu_noise_, T_b_i, T_b_c, options_.inertial_tracking);
    tracker_->set_inertial(inertial_tracking_.get());
    // Each keyframe is linked to the previous one of this session in its map
    // by the IMU between them, preintegrated at the map's bias estimate.
    // Each link carries the IMU in this session's camera: one map holds the
    // chains of sessions whose bodies differ (a single camera's is its camera,
    // a stereo rig's its IMU), and each chain's visual-inertial terms use its own.
    tracker_->set_keyframe_listener(
        [this, T_c_i = Pose3(T_b_c.inverse() * T_b_i)](const std::shared_ptr<KeyFrame>& made,
                                                       const std::shared_ptr<KeyFrame>& previous) {
          if (const auto state = inertial_tracking_->frame_state(made->timestamp_ns())) {
            const Eigen::Matrix3d R_w_i =
                (made->T_w_b() * options_.mapper.inertial.T_b_i).q.normalized().toRotationMatrix();
            const KeyFrame::ImuState imu{R_w_i.transpose() * state->v_w, state->bias};
            // A diverged estimate is left out (visual-inertial BA starts that
            // keyframe from its neighbours) rather than refused in tracking.
            if (imu.v_i.allFinite() && imu.bias.gyro.allFinite() && imu.bias.accel.allFinite())
              made->set_imu_state(imu);
          }
          if (!previous || previous->is_bad() || previous->map_id() != made->map_id()) return;
          // At this session's biases (its previous keyframe's), else the map's.
          ImuBias bias;
          if (const auto own = previous->imu_state()) {
            bias = own->bias;
          } else if (const auto map = atlas_.map(made->map_id())) {
            if (const auto state = map->inertial_state()) bias = state->bias;
          }
          auto increments = imu_.between(previous->timestamp_ns(), made->timestamp_ns(), bias, *imu_noise_);
          if (!increments) {
            ++imu_uncovered_;
            return;
          }
          note_white_noise(increments->noise());
          made->set_inertial_link(previous, std::make_shared<const Preintegration>(std::move(*increments)), T_c_i);
          ++imu_linked_;
        });
  }
}

void SlamSystem::note_white_noise(const ImuNoise& used) {
  link_gyro_density_.store(used.gyro_density);
  link_accel_density_.store(used.accel_density);
  // Logged once, for an excess beyond what a window's measurement spreads by
  // (within 10 % of the density).
  if (noisier_imu_logged_ ||
      (used.gyro_density < 1.25 * imu_noise_->gyro_density && used.accel_density < 1.25 * imu_noise_->accel_density))
    return;
  noisier_imu_logged_ = true;
  std::ostringstream message;
  message << "imu: the samples are noisier than the settings say; the increments use a white noise of "
          << used.gyro_density << " rad/s/sqrt(Hz) (IMU.NoiseGyro " << imu_noise_->gyro_density << ") and "
          << used.accel_density << " m/s^2/sqrt(Hz) (IMU.NoiseAcc " << imu_noise_->accel_density
          << "), what the samples show up to " << WhiteNoiseEstimateOptions{}.max_factor << " times the settings'";
  log_info(message.str());
}

void SlamSystem::add_imu(const std::vector<ImuSample>& samples) {
  if (imu_noise_) imu_.add(imu_input_->filter(samples));
}

SlamSystem::~SlamSystem() {
  // The tracker refers to the sink, the sink to the mapping: they go in that order.
  tracker_.reset();
  if (mapping_ && own_mapping_) {
    try {
      mapping_->finish();
    } catch (const std::exception& e) {
      log_warn(std::string("mapping stopped with an error: ") + e.what());
    }
  }
  sink_.reset();
  mapping_.reset();
}

TrackResult SlamSystem::process(TimestampNs t_ns, const cv::Mat& left, const cv::Mat& right) {
  ORBATLAS_CHECK(!finished_, "this SLAM session has finished; it takes no more frames");
  ORBATLAS_DATA_CHECK(monocular_ || !right.empty(), "a stereo session takes a stereo pair: the right image is missing");
  auto start = std::chrono::steady_clock::now();
  frontend_->set_map_starting(tracker_->state() == TrackingState::kNotInitialized ||
                              tracker_->state() == TrackingState::kLost);
  Frame frame = frontend_->make_frame(t_ns, left, right);
  if (imu_input_) imu_input_->check_frame(t_ns, imu_.time_offset());
  if (first_t_ns_.load() < 0) first_t_ns_.store(t_ns);
  // The front end does not read the map, so it runs while local mapping may
  // still adjust the session's last keyframe; tracking proper waits for that
  // here when asked (the wait is not counted in the frame's time).
  if (const auto waited = tracker_->wait_for_mapping()) {
    mapping_wait_ms_.add(*waited);
    start += std::chrono::duration_cast<std::chrono::steady_clock::duration>(
        std::chrono::duration<double, std::milli>(*waited));
  }
  const TrackResult result = frames_.track(*tracker_, std::move(frame), atlas_, start, options_.max_maps_wait_ms);
  if (imu_noise_ && !result.maps_busy) follow_imu_clock(result);
  if (result.keyframe) {
    ++keyframes_made_;
    if (options_.synchronous_mapping && mapping_) mapping_->wait_until_idle();
  }
  return result;
}

void SlamSystem::follow_imu_clock(const TrackResult& result) {
  if (result.map != time_offset_map_) {  // another map: its poses are in another frame
    time_offset_.reset();
    time_offset_map_ = result.map;
  }
  if (!result.tracked || result.by_imu) return;
  time_offset_.add_frame(result.t_ns, (result.T_w_b * T_b_i_).q);
  if (!time_offset_.update(imu_.samples())) return;
  const TimestampNs offset = s_to_ns(*time_offset_.offset_s());
  if (!time_offset_known_.load() || std::abs(offset - time_offset_ns_.load()) >= 500'000)
    log_info("camera-IMU clock offset: " + std::to_string(ns_to_s(offset) * 1e3).substr(0, 6) + " ms (from " +
             std::to_string(time_offset_.windows()) + " windows of the gyro against the images' rotation)");
  imu_.set_time_offset(offset);
  time_offset_ns_.store(offset);
  time_offset_known_.store(true);
}

void SlamSystem::finish() {
  if (finished_) return;
  finished_ = true;
  if (mapping_ && own_mapping_) {
    mapping_->finish();
  } else if (mapping_) {
    mapping_->wait_for_map(tracker_->map_id());  // its last keyframes are complete
    if (options_.shared_map_finish_wait_s > 0.0) {
      const auto wait = std::chrono::milliseconds(static_cast<long long>(options_.shared_map_finish_wait_s * 1000.0));
      end_refinement_ = [mapping = mapping_, map = tracker_->map_id(), wait] {
        if (mapping->refine_at_stream_end(map, wait)) return true;
        log_info("map " + std::to_string(map) + ": its global bundle adjustment at a session's end was not applied " +
                 "in time (it goes on)");
        return false;
      };
    }
  }
  tracker_->release_frames();
  // Nothing else edits these maps now: mapping and loop closing have stopped.
  if (options_.final_global_ba && mapping_ && own_mapping_) adjust_maps_globally(tracked_maps());
}

std::set<MapId> SlamSystem::tracked_maps() const {
  std::set<MapId> maps;
  for (const auto& anchor : frames_.anchors())
    if (const auto located = atlas_.locate_frame(anchor)) maps.insert(located->first);
  return maps;
}

void SlamSystem::adjust_maps_globally(const std::set<MapId>& maps) {
  const auto start = std::chrono::steady_clock::now();
  for (const MapId id : maps) {
    const auto map = atlas_.map(id);
    if (!map || map->keyframe_count() < 2) continue;
    const GlobalBundleAdjustmentResult result = global_bundle_adjustment(
        *map, *cam_.camera, cam_.bf, with_level_sigma2(options_.final_ba, cam_.pyramid.level_sigma2()));
    {
      const auto whole = atlas_.lock_maps_exclusive();  // other sessions' localisations see it whole
      apply_global_adjustment(*map, result, cam_.pyramid);
    }
    final_ba_keyframes_ += result.keyframes;
    final_ba_inertial_edges_ += result.inertial_edges;
  }
  final_ba_s_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

std::vector<TimedPose> SlamSystem::trajectory() const {
  const std::vector<FrameAnchor> anchors = frames_.anchors();
  std::vector<TimedPose> out;
  out.reserve(anchors.size());
  for (const auto& anchor : anchors)
    if (const auto located = atlas_.locate_frame(anchor))  // the map it is in now (merges move frames)
      out.push_back({anchor.t_ns, located->first, located->second});
  return out;
}

std::vector<FrameAnchor> SlamSystem::anchors_from(std::size_t first) const { return frames_.anchors_from(first); }

std::size_t SlamSystem::worker_errors() const { return frames_.errors().errors + (mapping_ ? mapping_->errors() : 0); }

SlamStats SlamSystem::stats() const {
  SlamStats s;
  s.frames = frames_.frames();
  s.relocalizations = tracker_->relocalizations();
  s.maps_started = tracker_->maps_started();
  s.final_ba_keyframes = final_ba_keyframes_;
  s.final_ba_inertial_edges = final_ba_inertial_edges_;
  s.final_ba_s = final_ba_s_;
  s.tracked = frames_.tracked();
  s.frames_tracked_by_imu = frames_.tracked_by_imu();
  s.lost = s.frames - s.tracked - s.frames_tracked_by_imu;
  s.tracking_errors = frames_.errors();
  s.slot_races = tracker_->slot_races();
  s.mapping_waits_cut = tracker_->mapping_waits_cut();
  s.mapping_wait_ms = mapping_wait_ms_;
  if (monocular_) {
    s.monocular = true;
    s.monocular_attempts = tracker_->monocular_attempts();
    s.monocular_starts = tracker_->monocular_starts();
  }
  s.keyframes_made = keyframes_made_;
  add_atlas_counts(atlas_, s);
  frames_.report(s);
  if (mapping_) {
    s.mapping = mapping_->mapping_stats();
    if (mapping_->loop_closing()) {
      s.loop_closing = true;
      s.loop = mapping_->loop_stats();
    }
  }
  s.culling_scheme = options_.mapper.culling.scheme;
  if (imu_noise_) {
    s.inertial = true;
    s.imu_samples = imu_.total();
    s.imu_linked_keyframes = imu_linked_.load();
    s.imu_uncovered_keyframes = imu_uncovered_.load();
    s.frames_optimized_with_imu = inertial_tracking_ ? inertial_tracking_->optimized_frames() : 0;
    if (time_offset_known_.load()) s.imu_time_offset_ms = ns_to_s(time_offset_ns_.load()) * 1e3;
    s.imu_input = imu_input_->health();
    if (link_gyro_density_.load() > 0.0)
      s.imu_white_noise = WhiteNoiseDensities{link_gyro_density_.load(), link_accel_density_.load()};
    // The map the session tracked in last (after merges: the one it is in now).
    if (const auto last = frames_.last_anchor())
      if (const auto located = atlas_.locate_frame(*last))
        if (const auto map = atlas_.map(located->first))
          if (const auto state = map->inertial_state()) {
            s.imu_initialized_at_s = ns_to_s(state->initialized_at_ns - first_t_ns_.load());
            s.imu_gravity_w = state->gravity_w;
            s.imu_bias = state->bias;
            s.imu_scale = state->scale;
          }
  }
  return s;
}

}  // namespace orbatlas
