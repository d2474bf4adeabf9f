#include "core/io/tum_rgbd.h"

#include "core/io/recording_paths.h"

#include <algorithm>
#include <fstream>
#include <limits>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "core/common/error.h"
#include "core/io/recording_paths.h"
#include "core/io/tum_trajectory.h"

namespace orbatlas {
namespace {

struct ListEntry {
  TimestampNs t_ns = 0;
  std::filesystem::path file;
};

// "timestamp filename" lines of rgb.txt or depth.txt.
std::vector<ListEntry> read_list(const std::filesystem::path& dir, const std::string& name,
                                 const RecordingConfinement& confinement) {
  const std::string path = (dir / name).string();
  std::ifstream in(path);
  ORBATLAS_DATA_CHECK(in.good(), path << " not found (a TUM RGB-D dataset lists its images in rgb.txt and depth.txt)");
  std::vector<ListEntry> entries;
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const auto first = line.find_first_not_of(" \t");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream fields(line);
    std::string stamp, file;
    fields >> stamp >> file;
    const auto t = parse_seconds_exact(stamp);
    ORBATLAS_DATA_CHECK(t.has_value() && !file.empty(),
                        path << ":" << number << ": expected \"timestamp filename\", got \"" << line << "\"");
    ORBATLAS_DATA_CHECK(entries.empty() || *t > entries.back().t_ns,
                        path << ":" << number << ": timestamps must increase");
    const std::filesystem::path listed = recording_file(dir, file, confinement, path, number);
    ORBATLAS_DATA_CHECK(std::filesystem::exists(listed), path << ":" << number << ": " << listed << " does not exist");
    entries.push_back({*t, listed});
  }
  return entries;
}

void write_list(const std::filesystem::path& path, const std::string& what,
                const std::vector<std::pair<TimestampNs, std::string>>& entries) {
  std::ofstream out(path);
  out << "# " << what << " images\n# timestamp filename\n";
  for (const auto& [t, file] : entries) out << format_seconds_exact(t) << ' ' << file << '\n';
  ORBATLAS_CHECK(out.good(), "cannot write " << path);
}

}  // namespace

TumRgbdDataset read_tum_rgbd(const std::filesystem::path& dir, double max_dt_s, bool confined) {
  TumRgbdDataset d;
  d.root = dir;
  const RecordingConfinement confinement{confined ? dir : std::filesystem::path()};
  const std::vector<ListEntry> rgb = read_list(dir, "rgb.txt", confinement),
                               depth = read_list(dir, "depth.txt", confinement);
  const TimestampNs max_dt = s_to_ns(max_dt_s);
  std::size_t j = 0;
  for (const ListEntry& c : rgb) {
    while (j + 1 < depth.size() && std::abs(depth[j + 1].t_ns - c.t_ns) <= std::abs(depth[j].t_ns - c.t_ns)) ++j;
    if (depth.empty() || std::abs(depth[j].t_ns - c.t_ns) > max_dt) {
      ++d.unpaired;
      continue;
    }
    d.frames.push_back({c.t_ns, depth[j].t_ns, c.file, depth[j].file});
  }
  if (std::filesystem::exists(dir / "groundtruth.txt")) d.ground_truth = read_tum_trajectory(dir / "groundtruth.txt");
  return d;
}

std::vector<DatasetFrame> rgbd_image_pairs(const TumRgbdDataset& dataset) {
  std::vector<DatasetFrame> pairs;
  for (const RgbdFrame& f : dataset.frames) pairs.push_back({f.t_ns, f.rgb, f.depth});
  return pairs;
}

std::vector<GroundTruthState> ground_truth_states(const TumRgbdDataset& dataset) {
  return ground_truth_states(dataset.ground_truth);
}

void keep_time_window(std::vector<RgbdFrame>& frames, double start_s, std::optional<double> duration_s,
                      const std::filesystem::path& dataset) {
  if (frames.empty()) return;
  const TimestampNs from = frames.front().t_ns + s_to_ns(start_s);
  const TimestampNs to = duration_s ? from + s_to_ns(*duration_s) : std::numeric_limits<TimestampNs>::max();
  std::erase_if(frames, [&](const RgbdFrame& f) { return f.t_ns < from || f.t_ns > to; });
  ORBATLAS_CHECK(!frames.empty(), dataset << ": no frame in the time window asked for");
}

cv::Mat read_depth_image(const std::filesystem::path& path, int width, int height) {
  const cv::Mat depth = cv::imread(path.string(), cv::IMREAD_UNCHANGED);
  ORBATLAS_DATA_CHECK(!depth.empty(), path << ": cannot read the depth image");
  ORBATLAS_DATA_CHECK(depth.type() == CV_16UC1, path << ": a depth image must be 16-bit single-channel");
  ORBATLAS_DATA_CHECK(depth.cols == width && depth.rows == height, path << ": depth image of " << depth.cols << "x"
                                                                        << depth.rows << ", the camera's is " << width
                                                                        << "x" << height);
  return depth;
}

TumRgbdWriter::TumRgbdWriter(const std::filesystem::path& dir) : dir_(dir) {
  ORBATLAS_CHECK(!std::filesystem::exists(dir / "rgb.txt"), dir << " already holds a TUM RGB-D dataset");
  std::filesystem::create_directories(dir / "rgb");
  std::filesystem::create_directories(dir / "depth");
}

void TumRgbdWriter::add(TimestampNs t_ns, const cv::Mat& image, TimestampNs depth_t_ns, const cv::Mat& depth) {
  ORBATLAS_CHECK(image.type() == CV_8UC1 || image.type() == CV_8UC3, "TUM RGB-D: 8-bit images only");
  ORBATLAS_CHECK(depth.type() == CV_16UC1 && depth.size() == image.size(),
                 "TUM RGB-D: the depth must be 16-bit of the image's size");
  ORBATLAS_CHECK(frames_.empty() || (t_ns > frames_.back().t_ns && depth_t_ns > frames_.back().depth_t_ns),
                 "TUM RGB-D: timestamps must increase");
  const std::string stamp = format_seconds_exact(t_ns), depth_stamp = format_seconds_exact(depth_t_ns);
  RgbdFrame f{t_ns, depth_t_ns, std::filesystem::path("rgb") / (stamp + ".png"),
              std::filesystem::path("depth") / (depth_stamp + ".png")};
  ORBATLAS_CHECK(cv::imwrite((dir_ / f.rgb).string(), image), "cannot write " << dir_ / f.rgb);
  ORBATLAS_CHECK(cv::imwrite((dir_ / f.depth).string(), depth), "cannot write " << dir_ / f.depth);
  frames_.push_back(std::move(f));
}

void write_tum_rgbd_lists(const std::filesystem::path& dir, const std::vector<RgbdFrame>& frames,
                          const Trajectory& ground_truth) {
  std::vector<std::pair<TimestampNs, std::string>> rgb, depth;
  for (const RgbdFrame& f : frames) {
    rgb.emplace_back(f.t_ns, f.rgb.generic_string());
    depth.emplace_back(f.depth_t_ns, f.depth.generic_string());
  }
  write_list(dir / "rgb.txt", "color", rgb);
  write_list(dir / "depth.txt", "depth", depth);
  if (!ground_truth.empty()) write_tum_trajectory(dir / "groundtruth.txt", ground_truth);
}

void TumRgbdWriter::finish(const Trajectory& ground_truth) { write_tum_rgbd_lists(dir_, frames_, ground_truth); }

}  // namespace orbatlas
