#include "core/pipeline/dataset_runner.h"

#include <chrono>
#include <cmath>
#include <functional>
#include <map>
#include <mutex>
#include <set>
#include <thread>

#include "core/common/error.h"
#include "core/common/log.h"
#include "core/common/process_memory.h"
#include "core/common/progress.h"
#include "core/common/worker_errors.h"
#include "core/eval/evaluate.h"
#include "core/eval/gap_error.h"
#include "core/eval/live_pose_jumps.h"
#include "core/io/euroc_reader.h"
#include "core/io/imu_batches.h"
#include "core/io/frame_loader.h"
#include "core/io/tum_trajectory.h"
#include "core/persistence/atlas_location.h"
#include "core/persistence/atlas_store.h"
#include "core/persistence/database_lock.h"
#include "core/persistence/map_rigs.h"
#include "core/pipeline/run_inputs.h"
#include "core/vocabulary/default_vocabulary.h"

namespace orbatlas {
namespace {

using Clock = std::chrono::steady_clock;

}  // namespace

namespace {

// The stored atlas a run works with (--atlas): its maps loaded into `atlas`, and,
// for a run that maps, the database lock, the new session and the camera rigs of
// the stored maps.
struct StoredAtlas {
  std::optional<SessionInfo> session;  // this run's, when it maps into the atlas
  std::map<MapId, MapRig> rigs;        // of the stored maps, by their sessions
  std::unique_ptr<DatabaseLock> lock;  // while this run may write the atlas
};

SessionInfo new_session(const DatasetRunOptions& options, const SlamSettings& settings, AtlasStore& store,
                        const Atlas& atlas, std::map<MapId, MapRig>& rigs) {
  SessionInfo info;
  for (const auto& stored : store.load_sessions()) {
    info.id = std::max(info.id, stored.id);
    record_map_rigs(atlas, stored, store.load_trajectory(stored.id), rigs);
  }
  ++info.id;
  info.name = std::filesystem::absolute(options.dataset).lexically_normal().filename().string();
  if (info.name.empty()) info.name = options.dataset.string();
  info.sensor = settings.sensor;
  info.created_ns = static_cast<TimestampNs>(
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
          .count());
  info.cameras.push_back(settings.camera0);
  if (settings.camera1) info.cameras.push_back(*settings.camera1);
  return info;
}

StoredAtlas open_atlas(const DatasetRunOptions& options, const SlamSettings& settings, const Vocabulary& vocabulary,
                       Atlas& atlas, DatasetRunReport& report) {
  StoredAtlas stored;
  if (options.atlas.empty()) return stored;
  // For messages: a PostgreSQL URI's password is never printed.
  const std::string shown = location_for_messages(options.atlas.string());
  if (!options.localize_only) stored.lock = std::make_unique<DatabaseLock>(options.atlas);
  const auto load_start = Clock::now();
  if (options.localize_only && !is_postgres_location(options.atlas.string()))
    ORBATLAS_CHECK(std::filesystem::exists(options.atlas), shown << " does not exist");
  AtlasStore store = AtlasStore::open(options.atlas, vocabulary.hash());
  const AtlasLoadReport loaded = store.load_atlas(atlas, &vocabulary);
  atlas.index_all_keyframes();
  if (stored.lock && stored.lock->previous_holder_crashed()) {
    skip_ids_after_crash(atlas);
    log_warn(shown +
             ": its previous writer stopped without a final checkpoint; new ids continue "
             "past any it may have handed out");
  }
  report.loaded_maps = loaded.maps;
  report.loaded_keyframes = loaded.keyframes;
  report.atlas_load_s = std::chrono::duration<double>(Clock::now() - load_start).count();
  log_info("atlas " + shown + ": " + std::to_string(loaded.maps) + " maps, " + std::to_string(loaded.keyframes) +
           " keyframes, " + std::to_string(loaded.map_points) + " map points loaded in " +
           std::to_string(report.atlas_load_s) + " s");
  if (options.localize_only) {
    ORBATLAS_DATA_CHECK(loaded.keyframes > 0, shown << " holds no keyframe to localise against");
  } else {
    stored.session = new_session(options, settings, store, atlas, stored.rigs);
    report.session = stored.session->id;
  }
  return stored;
}

// A run that maps into an atlas enters and merges into stored maps of its own
// camera rig only.
SessionWiring run_wiring(const StoredAtlas& stored) {
  SessionWiring wiring;
  if (stored.session) {
    const auto own_rig = [rigs = stored.rigs, rig = stored.session->cameras](MapId map) {
      const auto it = rigs.find(map);
      return it == rigs.end() || same_rig(it->second.cameras, rig);
    };
    wiring.may_enter_map = own_rig;
    wiring.may_merge_into = own_rig;
  }
  return wiring;
}

// The SLAM options of this run: a localisation changes nothing. Offline (not
// --realtime) tracking waits for local mapping to adjust each keyframe
// (TrackerOptions::max_mapping_wait_ms, unless set): frames come as fast as
// they are tracked, and a run that outpaced its mapping would track on into
// places its map has no points for yet (a visual-inertial local BA takes
// several frame intervals); the figures are then those of a machine whose
// mapping keeps up, whatever this one's speed.
SlamSystemOptions run_slam_options(const DatasetRunOptions& options) {
  SlamSystemOptions slam_options = options.slam;
  if (!options.realtime && slam_options.tracker.max_mapping_wait_ms == 0.0)
    slam_options.tracker.max_mapping_wait_ms = TrackerOptions::kLongestMappingWaitMs;
  if (options.localize_only) {
    slam_options.tracker.localization_only = true;
    slam_options.relocalization = true;
    slam_options.loop_closing = false;
  }
  return slam_options;
}

// A frame's part in the blackout's figures: the IMU carried it through the gap;
// after the gap, the frames until the first one tracked visually.
void note_black_out(DatasetRunReport::BlackOut& b, bool blacked, const TrackResult& r, std::size_t& after) {
  if (blacked) {
    if (r.by_imu) ++b.by_imu;
    return;
  }
  if (b.frames == 0 || b.frames_to_visual) return;  // before the gap, or recovered
  if (r.tracked && !r.by_imu) {
    b.frames_to_visual = after;
  } else {
    ++after;
  }
}

// Every frame through SLAM (decoded ahead on a loader thread), paced at the sensor
// rate with --realtime; bad frames are skipped and counted; a failure that leaves
// the map unusable stops the run with what was tracked.
void feed_frames(const DatasetRunOptions& options, const std::vector<DatasetFrame>& frames,
                 const std::vector<ImuSample>& imu, SlamSystem& slam, AtlasCheckpointer* checkpointer,
                 Clock::time_point wall_start, DatasetRunReport& report, const std::string& label = "run") {
  // Decodes images ahead of tracking (an RGB-D frame's second image is its depth).
  FrameLoader loaded(frames, 4, slam.rgbd() ? FrameLoader::Second::kDepth : FrameLoader::Second::kImage);
  Progress progress(label, static_cast<std::int64_t>(frames.size()), options.show_progress);
  std::size_t index = 0, imu_next = 0;
  std::size_t after_black_out = 0;  // frames since the gap ended, not tracked visually
  if (options.black_out_s) report.black_out.emplace();
  LivePoseJumps jumps;
  while (auto pair = loaded.next()) {
    if (slam.inertial()) {
      // The IMU up to this frame and the first sample after it (as a device
      // sends it), before the frame.
      slam.add_imu(take_imu_batch(imu, imu_next, pair->t_ns));
    }
    const TimestampNs next_t = index + 1 < frames.size() ? frames[index + 1].t_ns : pair->t_ns;
    ++index;
    if (options.realtime) {
      std::this_thread::sleep_until(wall_start + std::chrono::nanoseconds(pair->t_ns - frames.front().t_ns));
    }
    bool blacked = false;
    if (options.black_out_s && pair->error.empty()) {
      const double t = ns_to_s(pair->t_ns - frames.front().t_ns);
      blacked = t >= options.black_out_s->first && t < options.black_out_s->second;
      if (blacked) {
        pair->left = cv::Mat::zeros(pair->left.size(), pair->left.type());
        pair->right = cv::Mat::zeros(pair->right.size(), pair->right.type());
        ++report.black_out->frames;
      }
    }
    if (!pair->error.empty()) {
      log_warn(pair->error + " (frame skipped)");
      ++report.skipped_frames;
    } else {
      try {
        const TrackResult r = slam.process(pair->t_ns, pair->left, pair->right);
        if (report.black_out) note_black_out(*report.black_out, blacked, r, after_black_out);
        if (r.tracked) {
          report.live_trajectory.push_back({r.t_ns, r.T_w_b});
          report.live_maps.push_back(r.map);
          if (const auto jump = jumps.add(r.T_w_b.t, r.map, r.maps_edits)) report.live_jumps_m.push_back(*jump);
        } else {
          jumps.lost();
        }
        if (r.keyframe && checkpointer) {
          if (report.session) {
            checkpointer->notify_keyframe(*report.session, r.keyframe_id);
          } else {
            checkpointer->notify_keyframe();
          }
        }
      } catch (const DataError& e) {
        log_warn(std::string("frame at ") + std::to_string(pair->t_ns) + " ns skipped: " + e.what());
        ++report.skipped_frames;
      } catch (const WorkerFailed& e) {
        // The map cannot be worked on any more: stop here, keep what was tracked.
        report.failed = e.what();
        log_warn(std::string("the run stops at ") + std::to_string(pair->t_ns) + " ns: " + e.what());
        break;
      }
    }
    if (options.realtime && index < frames.size() &&
        Clock::now() > wall_start + std::chrono::nanoseconds(next_t - frames.front().t_ns))
      ++report.late_frames;
    progress.advance();
  }
  progress.finish();
}

// Lets mapping and loop closing finish, then writes the final durable checkpoint
// (every keyframe and the whole trajectory) and records a clean stop.
void finish_session(SlamSystem& slam, DatasetRunReport& report) {
  try {
    slam.finish();
    if (const auto refine = slam.take_end_refinement()) refine();
  } catch (const WorkerFailed& e) {
    if (report.failed.empty()) report.failed = e.what();
  }
}

void finish_storage(AtlasCheckpointer* checkpointer, DatabaseLock* lock, DatasetRunReport& report) {
  if (!checkpointer) return;
  checkpointer->stop();
  report.checkpoints = checkpointer->stats();
  if (!report.checkpoints->last_failed && lock) lock->mark_stopped();
  if (report.checkpoints->failures > 0)
    log_warn("atlas checkpoints failed " + std::to_string(report.checkpoints->failures) +
             " times; last error: " + report.checkpoints->last_error);
}

// The trajectory and figures of the run, and with ground truth its ATE and each
// closed loop's relative pose error (false loops).
void collect_results(const SlamSystem& slam, const EurocDataset& dataset, DatasetRunReport& report,
                     const std::optional<std::pair<double, double>>& black_out_s = std::nullopt,
                     TimestampNs first_frame_ns = 0) {
  for (const TimedPose& p : slam.trajectory()) {
    report.trajectory.push_back({p.t_ns, p.T_w_b});
    report.trajectory_maps.push_back(p.map);
  }
  report.stats = slam.stats();
  report.peak_rss_mb = peak_rss_mb();
  if (dataset.ground_truth.empty() || report.trajectory.size() < 3) return;
  const Trajectory gt = from_ground_truth_states(dataset.ground_truth);
  try {
    // A single camera reports the camera's poses, at the scale of its map
    // (metric once its IMU initialised it).
    EvalOptions eval;
    if (slam.monocular()) eval.estimate_T_b_x = slam.frontend().calibration().T_b_c;
    if (slam.monocular() && !slam.inertial()) eval.align = AlignMode::kSim3;
    report.ate_rmse_m = evaluate_trajectory(report.trajectory, gt, eval).ate.rmse;
    report.ate_sim3 = eval.align == AlignMode::kSim3;
    if (report.live_trajectory.size() >= 3)
      report.live_ate_rmse_m = evaluate_trajectory(report.live_trajectory, gt, eval).ate.rmse;
  } catch (const Error& e) {
    log_warn(std::string("no ATE: ") + e.what());
  }
  if (report.black_out && black_out_s && !report.trajectory.empty()) {
    const TimestampNs first = first_frame_ns;
    if (const auto gap = gap_error(report.trajectory, gt, first + s_to_ns(black_out_s->first),
                                   first + s_to_ns(black_out_s->second))) {
      report.black_out->error_at_end_m = gap->at_end_m;
      report.black_out->error_after_m = gap->after_m;
    }
  }
  const Pose3 T_b_c = slam.frontend().calibration().T_b_c;
  for (const ClosedLoop& loop : report.stats.loop.loops) {
    const auto a = pose_at(gt, loop.current_t_ns, 50'000'000);
    const auto m = pose_at(gt, loop.matched_t_ns, 50'000'000);
    if (!a || !m) break;  // errors stay index-aligned with the loops
    const Pose3 T_cur_m_gt = (*a * T_b_c).inverse() * (*m * T_b_c);
    report.stats.loop_error_m.push_back(translation_distance(T_cur_m_gt, loop.T_cur_m));
    report.stats.loop_error_deg.push_back(rotation_distance(T_cur_m_gt, loop.T_cur_m) * 180.0 / M_PI);
  }
}

}  // namespace

void DatasetRunOptions::check() const {
  ORBATLAS_CHECK(std::isfinite(start_s) && start_s >= 0.0, "run: start_s (--start) must be >= 0, not " << start_s);
  ORBATLAS_CHECK(!duration_s || (std::isfinite(*duration_s) && *duration_s > 0.0),
                 "run: duration_s (--duration) must be > 0, not " << duration_s.value_or(0.0));
  ORBATLAS_CHECK(!localize_only || !atlas.empty(), "run: localize_only needs a stored atlas (--atlas)");
  ORBATLAS_CHECK(!black_out_s || (std::isfinite(black_out_s->first) && black_out_s->first >= 0.0 &&
                                  std::isfinite(black_out_s->second) && black_out_s->second > black_out_s->first),
                 "run: the black-out must be FROM:TO seconds with 0 <= FROM < TO");
  slam.check();
  checkpoints.check();
}

DatasetRunReport run_dataset(const DatasetRunOptions& options) {
  options.check();
  const RunInputs in = read_run_inputs(options);
  const Vocabulary vocabulary =
      Vocabulary::load(options.vocabulary.empty() ? default_vocabulary_path() : options.vocabulary);
  // The stored trajectory keeps frames relative to keyframes in the map's
  // units, which a monocular-inertial map changes when its IMU initialises it.
  Atlas atlas;
  DatasetRunReport report;
  const StoredAtlas stored = open_atlas(options, in.settings, vocabulary, atlas, report);
  SlamSystem slam(atlas, in.settings, vocabulary, run_slam_options(options), run_wiring(stored));
  std::unique_ptr<AtlasCheckpointer> checkpointer;
  if (stored.session) {
    checkpointer = std::make_unique<AtlasCheckpointer>(
        atlas, options.atlas, vocabulary.hash(), options.checkpoints,
        CheckpointSession{*stored.session, [&slam](std::size_t first) { return slam.anchors_from(first); },
                          /*record=*/{}});
  }
  const auto wall_start = Clock::now();
  feed_frames(options, in.frames, in.dataset.imu, slam, checkpointer.get(), wall_start, report);
  finish_session(slam, report);
  finish_storage(checkpointer.get(), stored.lock.get(), report);
  report.wall_s = std::chrono::duration<double>(Clock::now() - wall_start).count();
  collect_results(slam, in.dataset, report, options.black_out_s, in.frames.empty() ? 0 : in.frames.front().t_ns);
  return report;
}

std::vector<DatasetRunReport> run_datasets(const DatasetRunOptions& options,
                                           const std::vector<std::filesystem::path>& datasets) {
  ORBATLAS_CHECK(!datasets.empty(), "run: no dataset given");
  const std::size_t n = datasets.size();
  std::vector<DatasetRunOptions> each(n, options);
  for (std::size_t i = 0; i < n; ++i) {
    each[i].dataset = datasets[i];
    each[i].show_progress = options.show_progress && i == 0;  // one progress line, the first recording's
  }
  if (n == 1) return {run_dataset(each[0])};
  options.check();
  std::vector<RunInputs> inputs;
  for (const auto& o : each) inputs.push_back(read_run_inputs(o));
  const Vocabulary vocabulary =
      Vocabulary::load(options.vocabulary.empty() ? default_vocabulary_path() : options.vocabulary);
  Atlas atlas;
  std::vector<DatasetRunReport> reports(n);
  const StoredAtlas stored = open_atlas(each[0], inputs[0].settings, vocabulary, atlas, reports[0]);
  // One session per recording (consecutive ids after the stored ones).
  std::vector<std::optional<SessionInfo>> sessions(n);
  sessions[0] = stored.session;
  for (std::size_t i = 1; i < n; ++i) {
    reports[i].loaded_maps = reports[0].loaded_maps;
    reports[i].loaded_keyframes = reports[0].loaded_keyframes;
    reports[i].atlas_load_s = reports[0].atlas_load_s;
    if (!stored.session) continue;
    SessionInfo info = *stored.session;
    info.id += i;
    info.name = std::filesystem::absolute(datasets[i]).lexically_normal().filename().string();
    sessions[i] = info;
    reports[i].session = info.id;
  }
  // One mapping for all of them (one rig: the same settings): local mapping
  // per map, fed by whichever recordings map in it, and loop closing over them.
  std::mutex mapping_mutex;
  std::shared_ptr<MappingWorkers> mapping;
  SessionWiring wiring = run_wiring(stored);
  wiring.mapping = [&](const FrameCamera& cam, const MappingWorkersOptions& mapping_options) {
    std::lock_guard lock(mapping_mutex);
    if (!mapping) {
      LoopCloserWiring loop_wiring;
      loop_wiring.may_merge_into = wiring.may_merge_into;
      mapping = std::make_shared<MappingWorkers>(atlas, cam, mapping_options, std::move(loop_wiring));
    }
    return mapping;
  };
  std::vector<std::unique_ptr<SlamSystem>> slams;
  for (std::size_t i = 0; i < n; ++i)
    slams.push_back(
        std::make_unique<SlamSystem>(atlas, inputs[i].settings, vocabulary, run_slam_options(each[i]), wiring));
  std::unique_ptr<AtlasCheckpointer> checkpointer;
  if (stored.session) {
    checkpointer = std::make_unique<AtlasCheckpointer>(
        atlas, options.atlas, vocabulary.hash(), options.checkpoints,
        CheckpointSession{*sessions[0],
                          [slam = slams[0].get()](std::size_t first) { return slam->anchors_from(first); },
                          /*record=*/{}});
    for (std::size_t i = 1; i < n; ++i)
      checkpointer->add_session(CheckpointSession{
          *sessions[i], [slam = slams[i].get()](std::size_t first) { return slam->anchors_from(first); },
          /*record=*/{}});
  }
  // Every recording on a thread of its own, at once.
  const auto wall_start = Clock::now();
  std::vector<std::thread> threads;
  for (std::size_t i = 0; i < n; ++i) {
    threads.emplace_back([&, i] {
      try {
        feed_frames(each[i], inputs[i].frames, inputs[i].dataset.imu, *slams[i], checkpointer.get(), wall_start,
                    reports[i], "run " + std::to_string(i + 1));
      } catch (const std::exception& e) {
        reports[i].failed = e.what();
        log_warn("recording " + datasets[i].string() + " stopped: " + e.what());
      }
    });
  }
  for (auto& t : threads) t.join();
  for (std::size_t i = 0; i < n; ++i) finish_session(*slams[i], reports[i]);
  if (mapping) {
    try {
      mapping->finish();  // the shared local mapping and loop closing, after every session
    } catch (const WorkerFailed& e) {
      for (auto& r : reports)
        if (r.failed.empty()) r.failed = e.what();
    }
  }
  if (options.slam.final_global_ba && mapping) {
    // --final-ba: the sessions' maps, once the mapping they shared has stopped
    // (each map once). A failure leaves the maps as mapped and is reported;
    // the trajectories and the checkpoint still follow.
    std::set<MapId> maps;
    for (const auto& slam : slams) maps.merge(slam->tracked_maps());
    try {
      slams.front()->adjust_maps_globally(maps);
    } catch (const std::exception& e) {
      log_warn(std::string("final global BA of the recordings' maps failed: ") + e.what());
      for (auto& r : reports)
        if (r.failed.empty()) r.failed = std::string("final global BA: ") + e.what();
    }
  }
  finish_storage(checkpointer.get(), stored.lock.get(), reports[0]);
  const double wall_s = std::chrono::duration<double>(Clock::now() - wall_start).count();
  for (std::size_t i = 0; i < n; ++i) {
    if (i > 0) reports[i].checkpoints = reports[0].checkpoints;
    reports[i].wall_s = wall_s;
    collect_results(*slams[i], inputs[i].dataset, reports[i], options.black_out_s,
                    inputs[i].frames.empty() ? 0 : inputs[i].frames.front().t_ns);
  }
  return reports;
}

}  // namespace orbatlas
