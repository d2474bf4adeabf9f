#include "client/api/dataset_streamer.h"

#include <chrono>
#include <cmath>
#include <fstream>
#include <optional>
#include <thread>
#include <unistd.h>

#include "core/common/error.h"
#include "core/common/log.h"
#include "core/common/progress.h"
#include "core/io/imu_batches.h"
#include "core/eval/evaluate.h"
#include "core/io/euroc_reader.h"
#include "core/io/preloaded_pairs.h"
#include "core/io/frame_loader.h"
#include "core/io/kitti_odometry.h"
#include "core/io/tum_rgbd.h"
#include "core/io/tum_trajectory.h"
#include "wire/pose_json.h"

namespace orbatlas {
namespace {

using Clock = std::chrono::steady_clock;

double ms_between(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

}  // namespace

void StreamOptions::check() const {
  ORBATLAS_CHECK(!dataset.empty(), "stream: no dataset folder given");
  ORBATLAS_CHECK(mode.empty() || mode == "map" || mode == "localize",
                 "stream: mode must be map or localize, not '" << mode << "'");
  ORBATLAS_CHECK(rate >= 0.0 && std::isfinite(rate), "stream: rate must be >= 0 (0: no pacing), not " << rate);
  ORBATLAS_CHECK(!max_lag_s || (std::isfinite(*max_lag_s) && *max_lag_s > 0.0),
                 "stream: max_lag_s must be > 0 s, not " << max_lag_s.value_or(0.0));
  ORBATLAS_CHECK(start_s >= 0.0 && std::isfinite(start_s), "stream: start_s must be >= 0 s, not " << start_s);
  ORBATLAS_CHECK(repeat >= 1 && repeat <= 1000, "stream: repeat must be in [1, 1000], not " << repeat);
  ORBATLAS_CHECK(!start_at_unix_s || (std::isfinite(*start_at_unix_s) && *start_at_unix_s > 0.0),
                 "stream: start_at_unix_s must be a time after the epoch, not " << start_at_unix_s.value_or(0.0));
  ORBATLAS_CHECK(!duration_s || (*duration_s > 0.0 && std::isfinite(*duration_s)),
                 "stream: duration_s must be > 0 s, not " << duration_s.value_or(0.0));
}

StreamReport stream_dataset(ServerClient& client, const StreamOptions& options) {
  options.check();
  // An ASL recording; an RGB-D one (the TUM layout: rgb.txt) may have no mav0/;
  // a KITTI odometry sequence has image_0/, image_1/, times.txt and calib.txt.
  const bool tum_layout = std::filesystem::exists(options.dataset / "rgb.txt");
  std::optional<KittiSequence> kitti;
  if (is_kitti_sequence(options.dataset)) kitti = read_kitti_sequence(options.dataset);
  EurocDataset dataset;
  if (kitti) {
    dataset.ground_truth = ground_truth_states(kitti->ground_truth);
  } else if (!tum_layout || std::filesystem::exists(options.dataset / "mav0")) {
    EurocReadOptions read_options;
    read_options.require_cam1 = false;  // a single camera needs cam0 only
    dataset = read_euroc_dataset(options.dataset, read_options);
    ORBATLAS_CHECK(!dataset.cameras.empty(), options.dataset << " has no camera");
  }

  StreamReport report;
  std::string name = options.name;
  if (name.empty()) name = std::filesystem::absolute(options.dataset).lexically_normal().filename().string();
  const bool settings_from_calib = kitti && options.config.empty();
  const nlohmann::json started = client.start_session(settings_from_calib      ? ""
                                                      : options.config.empty() ? "euroc/stereo"
                                                                               : options.config,
                                                      name, options.sensor, options.mode, options.max_lag_s,
                                                      settings_from_calib ? kitti_settings_yaml(*kitti) : "");
  report.session = started.at("id").get<std::uint64_t>();
  const std::string sensor = started.at("session").value("sensor", "stereo");
  const bool single_camera = sensor == "mono" || sensor == "mono_inertial";
  const bool rgbd = sensor == "rgbd";  // each colour image with its depth image (TUM RGB-D layout)
  // A single camera that maps reports its camera's poses at its map's scale.
  const bool monocular_map = single_camera && started.at("session").value("mode", "localize") == "map";
  // An inertial session gets the recording's imu0: before each frame, the
  // samples up to it and the first one past it.
  const bool send_imu = (sensor == "stereo_inertial" || sensor == "mono_inertial") && !dataset.imu.empty();
  std::size_t imu_next = 0;
  std::vector<DatasetFrame> frames;
  try {
    if (rgbd) {
      ORBATLAS_CHECK(tum_layout, options.dataset << " is not in the TUM RGB-D layout (rgb.txt, depth.txt) an rgbd "
                                                    "session streams");
      const TumRgbdDataset tum = read_tum_rgbd(options.dataset);
      frames = rgbd_image_pairs(tum);
      if (dataset.ground_truth.empty()) dataset.ground_truth = ground_truth_states(tum);
    } else if (kitti) {
      for (const DatasetFrame& f : kitti->frames)
        frames.push_back(single_camera ? DatasetFrame{f.t_ns, f.left, {}} : f);
    } else if (dataset.cameras.empty()) {
      throw Error(options.dataset.string() + " holds no ASL recording (mav0/) for a " + sensor + " session");
    } else if (single_camera) {
      for (const auto& f : dataset.cameras[0].frames) frames.push_back(DatasetFrame{f.t_ns, f.path, {}});
    } else {
      frames = pair_stereo_frames(dataset);
    }
    keep_time_window(frames, options.start_s, options.duration_s, options.dataset);
    if (options.repeat > 1) {
      ORBATLAS_CHECK(!send_imu,
                     "stream: --repeat is for sessions without an IMU (the " << sensor << " session would need it)");
      ORBATLAS_CHECK(frames.size() >= 2, "stream: --repeat needs at least two frames");
      // Each pass starts one frame interval after the last one ended.
      const TimestampNs step = (frames.back().t_ns - frames.front().t_ns) / static_cast<TimestampNs>(frames.size() - 1);
      const TimestampNs span = frames.back().t_ns - frames.front().t_ns + step;
      const std::size_t one = frames.size();
      frames.reserve(one * static_cast<std::size_t>(options.repeat));
      for (int pass = 1; pass < options.repeat; ++pass)
        for (std::size_t i = 0; i < one; ++i) {
          DatasetFrame f = frames[i];
          f.t_ns += span * pass;
          frames.push_back(std::move(f));
        }
      // The ground truth repeats with the frames, so each pass is compared with
      // the part of the recording it replays (not with what followed it).
      const TimestampNs t0 = frames.front().t_ns;
      std::vector<GroundTruthState> first_pass;
      for (const GroundTruthState& s : dataset.ground_truth)
        if (s.t_ns >= t0 && s.t_ns < t0 + span) first_pass.push_back(s);
      dataset.ground_truth.clear();
      for (int pass = 0; pass < options.repeat; ++pass)
        for (GroundTruthState s : first_pass) {
          s.t_ns += span * pass;
          dataset.ground_truth.push_back(s);
        }
    }
  } catch (...) {
    client.finish_session(report.session);  // nothing to stream: do not leave it live
    throw;
  }
  const TimestampNs first_t = frames.front().t_ns;

  Progress progress("stream", static_cast<std::int64_t>(frames.size()), options.show_progress);
  FrameLoader loaded(std::move(frames), 4, rgbd ? FrameLoader::Second::kDepth : FrameLoader::Second::kImage);
  // Preloaded pairs wait in an in-memory file, not as images in this
  // process's memory (core/io/preloaded_pairs.h says why).
  std::optional<PreloadedPairs> preloaded;
  if (options.preload) {
    preloaded.emplace();
    while (auto pair = loaded.next()) preloaded->push(*pair);
    log_info("stream: " + std::to_string(preloaded->size()) + " frames read and decoded before streaming (" +
             std::to_string(preloaded->bytes() >> 20) + " MB)");
  }
  const auto next_pair = [&]() -> std::optional<LoadedFrame> { return preloaded ? preloaded->pop() : loaded.next(); };
  // The frames' schedule starts at the start time itself, not when this
  // thread wakes after it: waking up took 5-110 ms on a loaded machine, and a
  // client's schedule anchored at its own wake-up put the cameras of "clients
  // started together" up to 89 ms apart for the whole run.
  auto start = Clock::now();
  if (options.start_at_unix_s) {
    const auto at =
        std::chrono::system_clock::time_point(std::chrono::duration_cast<std::chrono::system_clock::duration>(
            std::chrono::duration<double>(*options.start_at_unix_s)));
    const auto until = at - std::chrono::system_clock::now();
    if (until < std::chrono::system_clock::duration::zero()) {
      log_warn("stream: the start time had passed when the frames were ready; streaming at once");
    } else {
      start += std::chrono::duration_cast<Clock::duration>(until);
      std::this_thread::sleep_until(start);
    }
  }
  std::optional<Clock::time_point> last_reply;  // of the frame before this one
  while (!(options.stop && options.stop())) {
    auto pair = next_pair();
    if (!pair) break;
    if (options.rate > 0) {
      const auto due = start + std::chrono::nanoseconds(
                                   static_cast<std::int64_t>(static_cast<double>(pair->t_ns - first_t) / options.rate));
      if (last_reply && *last_reply > due) {
        ++report.late_frames;
        if (!report.frame_timings.empty()) report.frame_timings.back().late = true;
      }
      std::this_thread::sleep_until(due);
    }
    progress.advance();
    if (send_imu) {
      const std::vector<ImuSample> batch = take_imu_batch(dataset.imu, imu_next, pair->t_ns);
      if (!batch.empty()) {
        client.post_imu(report.session, batch);
        report.imu_samples += batch.size();
      }
    }
    if (!pair->error.empty()) {
      log_warn(pair->error + " (frame skipped)");
      ++report.rejected;
      continue;
    }
    const auto sent = Clock::now();
    const auto sent_unix = std::chrono::system_clock::now();
    try {
      const auto reply = client.post_frame(report.session, pair->t_ns, pair->left, pair->right, options.encoding);
      last_reply = Clock::now();
      StreamReport::FrameTiming timing;
      timing.t_ns = pair->t_ns;
      timing.sent_unix_us = std::chrono::duration_cast<std::chrono::microseconds>(sent_unix.time_since_epoch()).count();
      timing.round_trip_ms = ms_between(sent, *last_reply);
      if (reply.value("skipped", false)) {
        timing.skipped = true;
        report.frame_timings.push_back(timing);
        ++report.skipped_frames;
        continue;
      }
      timing.tracking_ms = reply.at("tracking_ms").get<double>();
      timing.server_ms = reply.at("server_ms").get<double>();
      timing.keyframe = reply.at("keyframe").get<bool>();
      timing.local_keyframes = reply.value("local_keyframes", 0);  // 0 from a server that does not say
      timing.local_points = reply.value("local_points", 0);
      timing.maps_wait_ms = reply.value("maps_wait_ms", 0.0);
      timing.maps_busy = reply.value("maps_busy", false);
      if (timing.maps_busy) ++report.maps_busy_frames;
      report.frame_timings.push_back(timing);
      report.round_trip_ms.push_back(timing.round_trip_ms);
      report.tracking_ms.push_back(timing.tracking_ms);
      report.server_ms.push_back(timing.server_ms);
      ++report.frames;
      if (reply.at("tracked").get<bool>()) {
        ++report.tracked;
        if (reply.contains("map")) report.reply_maps.push_back(reply.at("map").get<std::uint64_t>());
        if (reply.contains("T_w_b")) {
          report.live_trajectory.push_back({pair->t_ns, pose_from_json(reply.at("T_w_b"))});
          report.live_maps.push_back(reply.value("map", std::uint64_t{0}));
        }
        if (reply.contains("jump_m")) report.live_jumps_m.push_back(reply.at("jump_m").get<double>());
      }
      if (reply.at("keyframe").get<bool>()) ++report.keyframes;
    } catch (const ServerError& e) {
      if (e.status() != 422) throw;  // bad input: counted; anything else ends the stream
      log_warn(std::string("frame at ") + std::to_string(pair->t_ns) + " refused: " + e.what());
      ++report.rejected;
    }
  }
  report.wall_s = std::chrono::duration<double>(Clock::now() - start).count();
  progress.finish();
  const auto finishing = Clock::now();
  report.finish_status = client.finish_session(report.session);
  report.finish_ms = ms_between(finishing, Clock::now());
  report.trajectory = parse_tum_trajectory(client.trajectory_tum(report.session),
                                           "the server's trajectory of session " + std::to_string(report.session),
                                           &report.trajectory_maps);
  if (!dataset.ground_truth.empty() && report.trajectory.size() >= 3) {
    try {
      EvalOptions eval;
      if (monocular_map) {
        // The camera's poses; at the map's own scale, unless the IMU made it metric.
        if (sensor != "mono_inertial") eval.align = AlignMode::kSim3;
        eval.estimate_T_b_x = kitti ? Pose3() : dataset.cameras[0].calibration.T_b_c;  // KITTI: camera 0 is the body
      }
      const Trajectory truth = from_ground_truth_states(dataset.ground_truth);
      const EvalResult result = evaluate_trajectory(report.trajectory, truth, eval);
      report.ate_rmse_m = result.ate.rmse;
      report.ate_poses = result.matched;
      report.ate_sim3 = eval.align == AlignMode::kSim3;
      if (report.live_trajectory.size() >= 3) {
        const EvalResult live = evaluate_trajectory(report.live_trajectory, truth, eval);
        report.live_ate_rmse_m = live.ate.rmse;
        report.live_ate_poses = live.matched;
      }
    } catch (const Error& e) {
      log_warn(std::string("no ATE: ") + e.what());
    }
  }
  return report;
}

}  // namespace orbatlas
