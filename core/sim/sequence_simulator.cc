#include "core/sim/sequence_simulator.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <functional>
#include <mutex>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <thread>

#include "core/camera/camera_factory.h"
#include "core/common/data_paths.h"
#include "core/common/error.h"
#include "core/common/log.h"
#include "core/common/progress.h"
#include "core/io/euroc_writer.h"
#include "core/io/tum_rgbd.h"
#include "core/io/settings.h"
#include "core/sim/euroc_sequences.h"
#include "core/sim/imu_synthesizer.h"
#include "core/sim/machine_hall.h"
#include "core/sim/recorded_imu.h"
#include "core/sim/real_camera.h"
#include "core/sim/renderer.h"
#include "core/sim/trajectory_spline.h"

namespace orbatlas::sim {
namespace {

using Clock = std::chrono::steady_clock;

// The calibration the real look renders with: the written one, slightly off
// as a good real calibration is (focal lengths by up to 0.05%, principal points
// by up to 0.1 px, each camera's mounting by up to 0.005 deg and 0.1 mm), times
// `scale`. What matters most for stereo is the disparity bias the two cameras'
// errors leave together: up to about 0.3 px here at scale 1, a few percent of
// the depth of a point 4 m away.
CameraCalibration perturbed(const CameraCalibration& written, double scale, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  CameraCalibration c = written;
  c.fx *= 1.0 + scale * 0.0005 * u(rng);
  c.fy *= 1.0 + scale * 0.0005 * u(rng);
  c.cx += scale * 0.1 * u(rng);
  c.cy += scale * 0.1 * u(rng);
  const Eigen::Vector3d axis = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
  const double angle = scale * 0.005 * M_PI / 180.0 * u(rng);
  const Pose3 error(Eigen::Quaterniond(Eigen::AngleAxisd(angle, axis)),
                    scale * 0.0001 * Eigen::Vector3d(u(rng), u(rng), u(rng)));
  c.T_b_c = c.T_b_c * error;
  return c;
}

std::uint64_t hash_name(const std::string& s) {
  std::uint64_t h = 1469598103934665603ULL;
  for (const char c : s) h = (h ^ static_cast<unsigned char>(c)) * 1099511628211ULL;
  return h;
}

}  // namespace

void SimulationOptions::check() const {
  ORBATLAS_CHECK(!out_dir.empty(), "sim: no output folder given (out_dir, --out)");
  if (depth) depth->check();
  ORBATLAS_CHECK(std::isfinite(start_s) && start_s >= 0.0, "sim: start_s (--start) must be >= 0, not " << start_s);
  ORBATLAS_CHECK(!std::isnan(duration_s),
                 "sim: duration_s (--duration) must be a number (negative: to the end), not " << duration_s);
  ORBATLAS_CHECK(every >= 1, "sim: every (--every) must be >= 1, not " << every);
  ORBATLAS_CHECK(imu == ImuSource::kSynthetic || imu == ImuSource::kReal,
                 "sim: imu (--imu) must be synthetic or real, not " << static_cast<int>(imu));
  ORBATLAS_CHECK(noise_sigma >= 0.0 && noise_sigma <= 50.0,
                 "sim: noise_sigma (--noise) must be in [0, 50] grey levels, not " << noise_sigma);
  ORBATLAS_CHECK(look == Look::kClean || look == Look::kReal,
                 "sim: look (--look) must be clean or real, not " << static_cast<int>(look));
  if (real) real->check();
  if (imu_errors) imu_errors->check();
  ORBATLAS_CHECK(images_from.empty() || !depth, "sim: --images-from cannot go with --depth");
  ORBATLAS_CHECK(threads >= 0, "sim: threads (--threads) must be >= 0 (0: all cores), not " << threads);
}

namespace {

// The depth image of the frame at t (TUM RGB-D layout, relative to the dataset).
std::filesystem::path depth_image_path(TimestampNs t) {
  return std::filesystem::path("depth") / (format_seconds_exact(t) + ".png");
}

}  // namespace

SimulationReport simulate_sequence(const SimulationOptions& options) {
  options.check();
  SimulationReport report;
  const SequenceInfo sequence = find_sequence(options.sequence);
  ORBATLAS_CHECK(options.imu == ImuSource::kSynthetic || !recorded_imu_path(sequence.name).empty(),
                 "sim: --imu real is only available for MH_01 and MH_05 (the real IMUs shipped); use --imu synthetic");
  const auto settings_path =
      options.settings.empty() ? shipped_config_dir() / "euroc" / "stereo_inertial.yaml" : options.settings;
  const SlamSettings settings = read_settings(settings_path, SensorType::kStereoInertial);
  ORBATLAS_CHECK(settings.camera1.has_value(), "sim: " << settings_path.string() << " describes no second camera");
  const ImuCalibration imu_cal = settings.imu.value_or(ImuCalibration{});
  const std::uint64_t sensor_seed = options.sensor_seed != 0 ? options.sensor_seed : hash_name(sequence.name);
  const bool real = options.look == Look::kReal;
  const RealLookOptions look = options.real.value_or(real_look_for(sequence.name));

  // Trajectory and frame times.
  const Trajectory gt = load_ground_truth(sequence);
  const TrajectorySpline spline(gt);
  const std::vector<TimestampNs> all_stamps = load_camera_timestamps(sequence);
  ORBATLAS_CHECK(!all_stamps.empty(), "sim: no camera timestamps for " << sequence.name);
  const TimestampNs t_begin = all_stamps.front() + s_to_ns(options.start_s);
  const TimestampNs t_end = options.duration_s < 0 ? all_stamps.back() : t_begin + s_to_ns(options.duration_s);
  std::vector<TimestampNs> stamps;
  std::size_t in_range = 0;
  for (const TimestampNs t : all_stamps) {
    if (t < t_begin || t > t_end) continue;
    if (in_range++ % static_cast<std::size_t>(options.every) != 0) continue;
    if (!spline.covers(t)) {
      ++report.frames_outside_gt;
      continue;
    }
    stamps.push_back(t);
  }
  if (report.frames_outside_gt > 0)
    log_info("sim: skipped " + std::to_string(report.frames_outside_gt) +
             " camera timestamps outside the ground truth of " + sequence.name);
  ORBATLAS_CHECK(!stamps.empty(), "sim: no camera frame of " << sequence.name << " in the requested time range");

  // Created before the slow work so that an occupied output folder fails at once.
  const std::vector<CameraCalibration> cams = {settings.camera0, *settings.camera1};
  EurocWriter writer(options.out_dir, cams, imu_cal);
  if (options.depth) std::filesystem::create_directories(options.out_dir / "depth");
  // What the images are rendered with: the written calibration, or (real
  // look) one slightly off it, as a real rig's calibration is.
  std::vector<CameraCalibration> render_cams = cams;
  if (real && look.calibration_error > 0.0) {
    std::mt19937_64 rng(sensor_seed ^ 0xCA11B7A7E5ULL);
    for (auto& c : render_cams) c = perturbed(c, look.calibration_error, rng);
  }

  // The world: the same hall for every Machine Hall sequence.
  const auto world_start = Clock::now();
  std::vector<Trajectory> keep_free =
      sequence.machine_hall ? load_machine_hall_trajectories() : std::vector<Trajectory>{gt};
  MachineHallOptions hall_options;
  hall_options.seed = options.scene_seed;
  hall_options.sparse_textures = real && look.sparse_textures;
  const World world = build_machine_hall(keep_free, hall_options);
  report.world_build_s = std::chrono::duration<double>(Clock::now() - world_start).count();
  log_info("sim: world with " + std::to_string(world.quads().size()) + " surfaces built in " +
           std::to_string(report.world_build_s).substr(0, 4) + " s");

  // IMU and ground truth: from 1 s before the first frame to just after the last.
  const TimestampNs imu_first = std::max(spline.start_ns(), stamps.front() - kNsPerSecond);
  const TimestampNs imu_last = std::min(spline.end_ns(), stamps.back() + kNsPerSecond / 10);
  ImuSynthesisOptions imu_options;
  imu_options.calibration = imu_cal;
  imu_options.seed = sensor_seed;
  imu_options.errors = options.imu_errors.value_or(real ? realistic_imu_errors() : ideal_imu_errors());
  // The grid runs through the first camera timestamp, like EuRoC's triggered cameras.
  const TimestampNs period = s_to_ns(1.0 / imu_cal.rate_hz);
  const TimestampNs grid_first = stamps.front() - ((stamps.front() - imu_first) / period) * period;
  SyntheticImu imu = synthesize_imu(spline, grid_first, imu_last, imu_options);
  if (options.imu == ImuSource::kReal) {
    imu.samples = load_recorded_imu(sequence.name, imu_first, imu_last, s_to_ns(imu_options.errors.time_offset_s));
    imu.states.clear();  // ground truth at the real IMU times; biases unknown (zero)
    for (const ImuSample& s : imu.samples) {
      if (!spline.covers(s.t_ns)) continue;
      const SplineState st = spline.evaluate(s.t_ns);
      GroundTruthState g;
      g.t_ns = s.t_ns;
      g.T_w_b = st.T_w_b;
      g.v_w = st.v_w;
      imu.states.push_back(g);
    }
  }
  writer.write_imu(imu.samples);
  writer.write_ground_truth(imu.states);
  report.imu_samples = imu.samples.size();

  // Images: workers take frames from a shared counter; each owns its renderers.
  const int threads =
      options.threads > 0 ? options.threads : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  std::vector<std::unique_ptr<Camera>> cameras;
  for (const auto& c : render_cams) cameras.push_back(make_camera(c));
  Progress progress("sim " + sequence.name, static_cast<std::int64_t>(stamps.size()), options.show_progress);
  std::atomic<std::size_t> next{0};
  std::atomic<std::int64_t> render_ns{0};
  std::atomic<std::int64_t> subframes_total{0}, exposure_us_total{0};
  std::mutex error_mutex;
  std::string first_error;
  const auto render_start = Clock::now();
  auto worker = [&]() {
    try {
      std::vector<std::unique_ptr<Renderer>> renderers;
      std::vector<RealCamera> real_cameras;
      RenderOptions ro;
      ro.noise_sigma = real ? 0.0 : options.noise_sigma;  // the real camera adds its own
      for (std::size_t c = 0; c < cameras.size(); ++c) {
        renderers.push_back(std::make_unique<Renderer>(world, *cameras[c], ro));
        if (real)
          real_cameras.emplace_back(look.camera, cameras[c]->width(), cameras[c]->height(), static_cast<int>(c),
                                    sensor_seed);
      }
      std::optional<DepthSensor> depth_sensor;
      if (options.depth) depth_sensor.emplace(*cameras[0], *options.depth);
      cv::Mat image, radiance, sum;
      const std::vector<int> png_params = {cv::IMWRITE_PNG_COMPRESSION, 1};
      for (std::size_t i = next++; i < stamps.size(); i = next++) {
        const TimestampNs t = stamps[i];
        const Pose3 T_w_b = spline.pose(t);
        for (std::size_t c = 0; c < renderers.size(); ++c) {
          const auto t0 = Clock::now();
          const std::uint64_t noise_seed = sensor_seed ^ (static_cast<std::uint64_t>(t) * 2 + c);
          if (!real) {
            renderers[c]->render(T_w_b * render_cams[c].T_b_c, image, noise_seed);
          } else {
            // Motion blur: the mean of renders spread over the exposure time,
            // as many as the image moves pixels meanwhile.
            const Exposure exposure = real_cameras[c].exposure_at(t);
            const SplineState state = spline.evaluate(t);
            const double motion_px_per_s =
                render_cams[c].fx * (state.omega_b.norm() + state.v_w.norm() / 2.0);  // rotation + translation at 2 m
            const int n = real_cameras[c].subframes(motion_px_per_s, exposure.exposure_s);
            const TimestampNs exposure_ns = s_to_ns(exposure.exposure_s);
            for (int k = 0; k < n; ++k) {
              TimestampNs tk =
                  t - exposure_ns / 2 + static_cast<TimestampNs>((k + 0.5) / n * static_cast<double>(exposure_ns));
              tk = std::clamp(tk, spline.start_ns(), spline.end_ns());
              renderers[c]->render(spline.pose(tk) * render_cams[c].T_b_c, image, noise_seed);
              image.convertTo(radiance, CV_32FC1);
              if (k == 0) {
                sum = radiance.clone();
              } else {
                sum += radiance;
              }
            }
            if (n > 1) sum /= static_cast<double>(n);
            real_cameras[c].develop(sum, exposure, image, noise_seed);
            subframes_total += n;
            exposure_us_total += static_cast<std::int64_t>(exposure.exposure_s * 1e6);
          }
          render_ns += std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now() - t0).count();
          const auto path = writer.image_path(static_cast<int>(c), t);
          if (!cv::imwrite(path.string(), image, png_params)) throw Error("cannot write " + path.string());
          if (c == 0 && depth_sensor) {
            // Of the last render (the real look's last subframe: within the exposure).
            const auto depth_path = options.out_dir / depth_image_path(t);
            if (!cv::imwrite(depth_path.string(), depth_sensor->measure(*renderers[0], noise_seed ^ 0xD397ULL),
                             png_params))
              throw Error("cannot write " + depth_path.string());
          }
        }
        progress.advance();
        std::lock_guard lock(error_mutex);
        if (!first_error.empty()) return;
      }
    } catch (const std::exception& e) {
      std::lock_guard lock(error_mutex);
      if (first_error.empty()) first_error = e.what();
      next = stamps.size();
    }
  };
  if (!options.images_from.empty()) {
    // An IMU variant of an earlier rendering: its images, linked.
    for (const TimestampNs t : stamps) {
      for (int c = 0; c < static_cast<int>(cams.size()); ++c) {
        const auto target = writer.image_path(c, t);
        const auto source = options.images_from / std::filesystem::relative(target, options.out_dir);
        ORBATLAS_CHECK(std::filesystem::is_regular_file(source),
                       "sim: --images-from " << options.images_from.string() << " has no " << source.string()
                                             << " (render the same sequence, look and range there first)");
        std::error_code error;
        std::filesystem::create_hard_link(source, target, error);
        if (error) std::filesystem::copy_file(source, target);
      }
      progress.advance();
    }
    next = stamps.size();
  }
  std::vector<std::thread> pool;
  for (int k = 0; k < threads && next < stamps.size(); ++k) pool.emplace_back(worker);
  for (auto& th : pool) th.join();
  progress.finish();
  if (!first_error.empty()) throw Error("sim: " + first_error);
  for (const TimestampNs t : stamps)
    for (int c = 0; c < static_cast<int>(cams.size()); ++c) writer.add_frame_row(c, t);
  writer.close();
  if (options.depth) {
    std::vector<RgbdFrame> frames;
    for (const TimestampNs t : stamps)
      frames.push_back(
          {t, t, std::filesystem::relative(writer.image_path(0, t), options.out_dir), depth_image_path(t)});
    Trajectory body;
    for (const GroundTruthState& s : imu.states) body.push_back({s.t_ns, s.T_w_b});
    write_tum_rgbd_lists(options.out_dir, frames, body);
    report.depth_images = frames.size();
  }

  report.frames = stamps.size();
  report.render_s = std::chrono::duration<double>(Clock::now() - render_start).count();
  report.render_ms_per_image = static_cast<double>(render_ns.load()) * 1e-6 / static_cast<double>(2 * stamps.size());
  if (real) {
    report.subframes_per_image = static_cast<double>(subframes_total.load()) / static_cast<double>(2 * stamps.size());
    report.mean_exposure_ms =
        static_cast<double>(exposure_us_total.load()) * 1e-3 / static_cast<double>(2 * stamps.size());
  }
  return report;
}

}  // namespace orbatlas::sim
