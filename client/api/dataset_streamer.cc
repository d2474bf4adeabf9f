#include "client/api/dataset_streamer.h"

#include <chrono>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <thread>
#include <unistd.h>

#include "core/common/bounded_queue.h"
#include "core/common/log.h"
#include "core/common/progress.h"
#include "core/eval/evaluate.h"
#include "core/io/euroc_reader.h"
#include "core/io/tum_trajectory.h"

namespace orbatlas {
namespace {

using Clock = std::chrono::steady_clock;

struct LoadedPair {
  TimestampNs t_ns = 0;
  cv::Mat left, right;
  std::string error;
};

double ms_between(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

// The server's TUM text as a trajectory (through a temporary file: one parser).
Trajectory parse_tum_text(const std::string& text, std::vector<std::uint64_t>& maps) {
  const auto path = std::filesystem::temp_directory_path() /
                    ("orbatlas-stream-" + std::to_string(::getpid()) + "-" +
                     std::to_string(Clock::now().time_since_epoch().count()) + ".txt");
  {
    std::ofstream out(path, std::ios::binary);
    out << text;
  }
  Trajectory t;
  try {
    t = read_tum_trajectory(path);
  } catch (...) {
    std::filesystem::remove(path);
    throw;
  }
  std::filesystem::remove(path);
  // "# map <id>" lines precede each run of poses of one map.
  std::size_t pos = 0;
  std::uint64_t current = 0;
  while (pos < text.size()) {
    std::size_t end = text.find('\n', pos);
    if (end == std::string::npos) end = text.size();
    const std::string line = text.substr(pos, end - pos);
    if (line.rfind("# map ", 0) == 0) {
      current = std::stoull(line.substr(6));
    } else if (!line.empty() && line[0] != '#') {
      maps.push_back(current);
    }
    pos = end + 1;
  }
  return t;
}

}  // namespace

StreamReport stream_dataset(ServerClient& client, const StreamOptions& options) {
  EurocReadOptions read_options;
  read_options.require_cam1 = true;
  const EurocDataset dataset = read_euroc_dataset(options.dataset, read_options);
  std::vector<StereoFrame> frames = pair_stereo_frames(dataset);
  ORBATLAS_CHECK(!frames.empty(), options.dataset << " has no stereo frames");
  const TimestampNs from = frames.front().t_ns + static_cast<TimestampNs>(options.start_s * 1e9);
  const TimestampNs to = options.duration_s ? from + static_cast<TimestampNs>(*options.duration_s * 1e9)
                                            : std::numeric_limits<TimestampNs>::max();
  std::erase_if(frames, [&](const StereoFrame& f) { return f.t_ns < from || f.t_ns >= to; });
  ORBATLAS_CHECK(!frames.empty(), "no frame of " << options.dataset << " lies in the chosen time window");

  StreamReport report;
  std::string name = options.name;
  if (name.empty()) name = std::filesystem::absolute(options.dataset).lexically_normal().filename().string();
  report.session = client.create_session(options.config, name);

  BoundedQueue<LoadedPair> loaded(4);
  std::thread loader([&] {
    for (const StereoFrame& f : frames) {
      LoadedPair pair;
      pair.t_ns = f.t_ns;
      pair.left = cv::imread(f.left.string(), cv::IMREAD_GRAYSCALE);
      pair.right = cv::imread(f.right.string(), cv::IMREAD_GRAYSCALE);
      if (pair.left.empty() || pair.right.empty()) pair.error = "cannot read the images at " + std::to_string(f.t_ns);
      if (!loaded.push(std::move(pair))) return;
    }
    loaded.close();
  });
  Progress progress("stream", static_cast<std::int64_t>(frames.size()), options.show_progress);
  const auto start = Clock::now();
  try {
    while (auto pair = loaded.pop()) {
      if (options.rate > 0) {
        const auto offset = std::chrono::nanoseconds(
            static_cast<std::int64_t>(static_cast<double>(pair->t_ns - frames.front().t_ns) / options.rate));
        std::this_thread::sleep_until(start + offset);
      }
      progress.advance();
      if (!pair->error.empty()) {
        log_warn(pair->error + " (frame skipped)");
        ++report.rejected;
        continue;
      }
      const auto sent = Clock::now();
      try {
        const auto reply = client.post_frame(report.session, pair->t_ns, pair->left, pair->right, options.encoding);
        report.round_trip_ms.push_back(ms_between(sent, Clock::now()));
        report.tracking_ms.push_back(reply.at("tracking_ms").get<double>());
        report.server_ms.push_back(reply.at("server_ms").get<double>());
        ++report.frames;
        if (reply.at("tracked").get<bool>()) ++report.tracked;
        if (reply.at("keyframe").get<bool>()) ++report.keyframes;
      } catch (const ServerError& e) {
        if (e.status() != 422) throw;  // bad input: counted; anything else ends the stream
        log_warn(std::string("frame at ") + std::to_string(pair->t_ns) + " refused: " + e.what());
        ++report.rejected;
      }
    }
  } catch (...) {
    loaded.close();
    loader.join();
    throw;
  }
  loader.join();
  report.wall_s = std::chrono::duration<double>(Clock::now() - start).count();
  progress.finish();
  report.finish_status = client.finish_session(report.session);
  report.trajectory = parse_tum_text(client.trajectory_tum(report.session), report.trajectory_maps);
  if (!dataset.ground_truth.empty() && report.trajectory.size() >= 3) {
    Trajectory gt;
    for (const auto& s : dataset.ground_truth) gt.push_back({s.t_ns, s.T_w_b});
    try {
      report.ate_rmse_m = evaluate_trajectory(report.trajectory, gt).ate.rmse;
    } catch (const Error& e) {
      log_warn(std::string("no ATE: ") + e.what());
    }
  }
  return report;
}

}  // namespace orbatlas
