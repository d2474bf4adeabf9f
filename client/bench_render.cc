// orbatlas bench render: milliseconds per rendered image, one thread.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <opencv2/core/utility.hpp>

#include "client/benchmarks.h"
#include "core/camera/camera_factory.h"
#include "core/common/data_paths.h"
#include "core/io/settings.h"
#include "core/sim/euroc_sequences.h"
#include "core/sim/machine_hall.h"
#include "core/sim/renderer.h"
#include "core/sim/trajectory_spline.h"

namespace orbatlas::cli {

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(p * static_cast<double>(v.size() - 1))];
}

void run_render_bench(const RenderBenchOptions& o) {
  o.check();
  cv::setNumThreads(1);  // one core: cv::remap would otherwise use every core
  using Clock = std::chrono::steady_clock;
  const SlamSettings settings = read_settings(shipped_config_dir() / "euroc" / "stereo_inertial.yaml");
  const auto camera = make_camera(settings.camera0);
  const sim::SequenceInfo seq = sim::find_sequence(o.sequence);
  const auto t_world = Clock::now();
  const sim::World world = sim::build_machine_hall(sim::load_machine_hall_trajectories(), {});
  const double world_s = std::chrono::duration<double>(Clock::now() - t_world).count();
  const sim::TrajectorySpline spline(sim::load_ground_truth(seq));
  std::vector<TimestampNs> stamps;
  for (const TimestampNs t : sim::load_camera_timestamps(seq))
    if (spline.covers(t)) stamps.push_back(t);
  sim::Renderer renderer(world, *camera);
  cv::Mat image;
  std::vector<double> ms;
  const std::size_t step = std::max<std::size_t>(1, stamps.size() / static_cast<std::size_t>(std::max(1, o.frames)));
  for (std::size_t i = 0; i < stamps.size() && ms.size() < static_cast<std::size_t>(o.frames); i += step) {
    const Pose3 T_w_c = spline.pose(stamps[i]) * settings.camera0.T_b_c;
    const auto t0 = Clock::now();
    renderer.render(T_w_c, image, i);
    ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
  }
  double mean = 0;
  for (const double m : ms) mean += m / static_cast<double>(ms.size());
  if (o.json) {
    nlohmann::json j = {{"benchmark", "render"},
                        {"sequence", seq.name},
                        {"images", ms.size()},
                        {"width", camera->width()},
                        {"height", camera->height()},
                        {"render_ms_p50", percentile(ms, 0.5)},
                        {"render_ms_p95", percentile(ms, 0.95)},
                        {"render_ms_mean", mean},
                        {"world_build_s", world_s},
                        {"world_quads", world.quads().size()},
                        {"world_texels", world.texel_count()}};
    std::printf("%s\n", j.dump(2).c_str());
  } else {
    std::printf("render benchmark: %zu images of %dx%d along %s, one thread\n", ms.size(), camera->width(),
                camera->height(), seq.name.c_str());
    std::printf("  ms per image: p50 %.2f  p95 %.2f  mean %.2f\n", percentile(ms, 0.5), percentile(ms, 0.95), mean);
    std::printf("  world: %zu quads, %.1f M texels, built in %.2f s\n", world.quads().size(),
                static_cast<double>(world.texel_count()) * 1e-6, world_s);
  }
}

}  // namespace orbatlas::cli
