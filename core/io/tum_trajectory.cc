// TUM trajectory files (and ORB-SLAM3's ns variant), plus ground truth in any form.
#include "core/io/tum_trajectory.h"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <string>
#include <string_view>

#include "core/common/error.h"
#include "core/common/text_file.h"
#include "core/io/euroc_reader.h"
#include "core/io/euroc_trajectory.h"
#include "core/io/kitti_odometry.h"

namespace orbatlas {
namespace {

namespace fs = std::filesystem;

constexpr std::uint64_t kNanosecondThreshold = 1'000'000'000'000ULL;  // 1e12: larger values are ns

[[noreturn]] void fail_at(const fs::path& path, std::size_t line, const std::string& what) {
  throw DataError(path.string() + ":" + std::to_string(line) + ": " + what);
}

bool all_digits(std::string_view s) {
  for (const char c : s)
    if (c < '0' || c > '9') return false;
  return true;
}

// "1403636580.83856" (seconds, exact) or "1403636586363555584.000000" (ns: the
// integer part exactly; a fraction rounds to the nearest ns).
std::optional<TimestampNs> parse_tum_timestamp(std::string_view text) {
  const std::size_t dot = text.find('.');
  const std::string_view whole = text.substr(0, dot);
  if (!whole.empty() && all_digits(whole)) {
    std::uint64_t value = 0;
    const auto [ptr, ec] = std::from_chars(whole.data(), whole.data() + whole.size(), value);
    if (ec != std::errc() || ptr != whole.data() + whole.size()) return std::nullopt;  // overflow
    if (value > kNanosecondThreshold) {
      const std::string_view frac = dot == std::string_view::npos ? std::string_view() : text.substr(dot + 1);
      if (!all_digits(frac)) return std::nullopt;
      if (value > static_cast<std::uint64_t>(std::numeric_limits<TimestampNs>::max()) - 1) return std::nullopt;
      return static_cast<TimestampNs>(value) + ((!frac.empty() && frac[0] >= '5') ? 1 : 0);
    }
  }
  return parse_seconds_exact(text);
}

bool is_comment_or_blank(std::string_view text) {
  const std::string_view t = trim(text);
  return t.empty() || t.front() == '#';
}

// The first data line of a file, split on commas; empty when there is none.
std::vector<std::string> first_csv_fields(const fs::path& path) {
  const std::string content = read_text_file(path);
  std::size_t pos = 0;
  while (pos < content.size()) {
    std::size_t end = content.find('\n', pos);
    if (end == std::string::npos) end = content.size();
    const std::string_view line(content.data() + pos, end - pos);
    if (!is_comment_or_blank(line)) {
      std::vector<std::string> out;
      for (const auto f : split_fields(line, ",", false)) out.emplace_back(f);
      return out;
    }
    pos = end + 1;
  }
  return {};
}

}  // namespace

Trajectory from_ground_truth_states(const std::vector<GroundTruthState>& states) {
  Trajectory trajectory;
  trajectory.reserve(states.size());
  for (const GroundTruthState& s : states) trajectory.push_back(StampedPose{s.t_ns, s.T_w_b});
  return trajectory;
}

Trajectory parse_tum_trajectory(const std::string& text, const fs::path& source, std::vector<std::uint64_t>* maps) {
  Trajectory trajectory;
  std::size_t previous_line = 0, number = 0, pos = 0;
  std::uint64_t map = 0;
  while (pos < text.size()) {
    std::size_t end = text.find('\n', pos);
    if (end == std::string::npos) end = text.size();
    std::string_view line(text.data() + pos, end - pos);
    pos = end + 1;
    ++number;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    if (line.rfind("# map ", 0) == 0) {
      map = static_cast<std::uint64_t>(parse_int64(trim(line.substr(6)), source, number));
      continue;
    }
    if (is_comment_or_blank(line)) continue;
    const auto f = split_fields(line, " \t,", true);
    if (f.size() != 8)
      fail_at(source, number, "expected 8 fields 't tx ty tz qx qy qz qw', found " + std::to_string(f.size()));
    const auto t = parse_tum_timestamp(f[0]);
    if (!t) fail_at(source, number, "bad timestamp '" + std::string(f[0]) + "'");
    double v[7];
    for (std::size_t i = 0; i < 7; ++i) {
      v[i] = parse_double(f[i + 1], source, number);
      if (!std::isfinite(v[i])) fail_at(source, number, "non-finite value '" + std::string(f[i + 1]) + "'");
    }
    const Eigen::Quaterniond q(v[6], v[3], v[4], v[5]);  // file order: qx qy qz qw
    if (std::abs(q.norm() - 1.0) > 1e-3)
      fail_at(source, number, "quaternion is not unit (|q| = " + std::to_string(q.norm()) + ")");
    if (!trajectory.empty() && *t <= trajectory.back().t_ns)
      fail_at(source, number,
              "timestamp " + format_seconds_exact(*t) + " is not after " +
                  format_seconds_exact(trajectory.back().t_ns) + " (line " + std::to_string(previous_line) + ")");
    previous_line = number;
    trajectory.push_back(StampedPose{*t, Pose3(q, Eigen::Vector3d(v[0], v[1], v[2]))});
    if (maps) maps->push_back(map);
  }
  return trajectory;
}

Trajectory read_tum_trajectory(const fs::path& path) { return parse_tum_trajectory(read_text_file(path), path); }

void write_tum_trajectory(const fs::path& path, const Trajectory& trajectory) {
  write_tum_trajectory(path, trajectory, {});
}

std::string format_tum_trajectory(const Trajectory& trajectory, const std::vector<std::uint64_t>& maps) {
  check_strictly_increasing(trajectory, "format_tum_trajectory");
  if (!maps.empty() && maps.size() != trajectory.size())
    throw Error("format_tum_trajectory: " + std::to_string(maps.size()) + " map ids for " +
                std::to_string(trajectory.size()) + " poses");
  std::string out = "# timestamp[s] tx ty tz qx qy qz qw\n";
  char buf[256];
  for (std::size_t i = 0; i < trajectory.size(); ++i) {
    const StampedPose& s = trajectory[i];
    if (!maps.empty() && (i == 0 || maps[i] != maps[i - 1])) out += "# map " + std::to_string(maps[i]) + "\n";
    const Eigen::Vector3d& p = s.pose.t;
    const Eigen::Quaterniond& q = s.pose.q;
    std::snprintf(buf, sizeof buf, " %.9f %.9f %.9f %.9f %.9f %.9f %.9f\n", p.x(), p.y(), p.z(), q.x(), q.y(), q.z(),
                  q.w());
    out += format_seconds_exact(s.t_ns);
    out += buf;
  }
  return out;
}

void write_tum_trajectory(const fs::path& path, const Trajectory& trajectory, const std::vector<std::uint64_t>& maps) {
  write_trajectory_text(path, format_tum_trajectory(trajectory, maps));
}

void write_trajectory_text(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw Error("cannot create " + path.string());
  out << text;
  out.close();
  if (!out) throw Error("cannot write " + path.string());
}

std::vector<GroundTruthState> ground_truth_states(const Trajectory& poses) {
  std::vector<GroundTruthState> states;
  states.reserve(poses.size());
  for (const StampedPose& p : poses) {
    GroundTruthState g;
    g.t_ns = p.t_ns;
    g.T_w_b = p.pose;
    states.push_back(g);
  }
  return states;
}

Trajectory read_any_ground_truth(const fs::path& path) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) {
    if (is_kitti_sequence(path)) return read_kitti_ground_truth(path);
    // The dataset folder, its mav0/, or state_groundtruth_estimate0/ itself.
    for (const fs::path& csv : {path / "mav0" / "state_groundtruth_estimate0" / "data.csv",
                                path / "state_groundtruth_estimate0" / "data.csv"}) {
      if (fs::is_regular_file(csv, ec)) return from_ground_truth_states(read_asl_ground_truth_csv(csv));
    }
    if (path.filename() == "state_groundtruth_estimate0" && fs::is_regular_file(path / "data.csv", ec))
      return from_ground_truth_states(read_asl_ground_truth_csv(path / "data.csv"));
    throw DataError(path.string() + ": folder has no mav0/state_groundtruth_estimate0/data.csv");
  }
  if (!fs::exists(path, ec)) throw DataError(path.string() + ": file not found");
  // An ASL ground-truth csv has 17 comma-separated columns; a EuRoC trajectory
  // csv (ours, evo's) 8 or more, its first an integer of nanoseconds; anything
  // else is read as TUM.
  const std::vector<std::string> fields = first_csv_fields(path);
  if (fields.size() == 17) return from_ground_truth_states(read_asl_ground_truth_csv(path));
  if (fields.size() >= 8 && !fields[0].empty() && all_digits(trim(fields[0]))) return read_euroc_trajectory(path);
  if (looks_like_kitti_poses(path)) return read_kitti_ground_truth(path);
  return read_tum_trajectory(path);
}

}  // namespace orbatlas
