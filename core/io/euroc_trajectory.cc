#include "core/io/euroc_trajectory.h"

#include <cmath>
#include <cstdio>
#include <string_view>

#include "core/common/error.h"
#include "core/common/text_file.h"
#include "core/io/tum_trajectory.h"

namespace orbatlas {
namespace {

[[noreturn]] void fail_at(const std::filesystem::path& path, std::size_t line, const std::string& what) {
  throw DataError(path.string() + ":" + std::to_string(line) + ": " + what);
}

}  // namespace

TrajectoryFormat parse_trajectory_format(const std::string& name) {
  if (name == "tum") return TrajectoryFormat::kTum;
  if (name == "euroc") return TrajectoryFormat::kEuroc;
  throw Error("trajectory format must be tum or euroc, not '" + name + "'");
}

std::string format_euroc_trajectory(const Trajectory& trajectory, const std::vector<std::uint64_t>& maps) {
  check_strictly_increasing(trajectory, "format_euroc_trajectory");
  if (!maps.empty() && maps.size() != trajectory.size())
    throw Error("format_euroc_trajectory: " + std::to_string(maps.size()) + " map ids for " +
                std::to_string(trajectory.size()) + " poses");
  std::string out = "#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x [],q_RS_y [],q_RS_z []\n";
  char buf[256];
  for (std::size_t i = 0; i < trajectory.size(); ++i) {
    const StampedPose& s = trajectory[i];
    if (!maps.empty() && (i == 0 || maps[i] != maps[i - 1])) out += "# map " + std::to_string(maps[i]) + "\n";
    const Eigen::Vector3d& p = s.pose.t;
    const Eigen::Quaterniond& q = s.pose.q;
    std::snprintf(buf, sizeof buf, "%lld,%.9f,%.9f,%.9f,%.9f,%.9f,%.9f,%.9f\n", static_cast<long long>(s.t_ns), p.x(),
                  p.y(), p.z(), q.w(), q.x(), q.y(), q.z());
    out += buf;
  }
  return out;
}

Trajectory parse_euroc_trajectory(const std::string& text, const std::filesystem::path& source) {
  Trajectory trajectory;
  std::size_t number = 0, pos = 0;
  while (pos < text.size()) {
    std::size_t end = text.find('\n', pos);
    if (end == std::string::npos) end = text.size();
    std::string_view line(text.data() + pos, end - pos);
    pos = end + 1;
    ++number;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    const std::string_view trimmed = trim(line);
    if (trimmed.empty() || trimmed.front() == '#') continue;
    const auto f = split_fields(trimmed, ",", false);
    if (f.size() < 8)
      fail_at(source, number,
              "expected 8 fields 'timestamp [ns],px,py,pz,qw,qx,qy,qz', found " + std::to_string(f.size()));
    const std::string_view stamp = trim(f[0]);
    if (stamp.empty() || stamp.find_first_not_of("0123456789") != std::string_view::npos)
      fail_at(source, number, "the timestamp '" + std::string(stamp) + "' is not an integer of nanoseconds");
    const TimestampNs t = parse_int64(stamp, source, number);
    double v[7];
    for (std::size_t i = 0; i < 7; ++i) {
      v[i] = parse_double(trim(f[i + 1]), source, number);
      if (!std::isfinite(v[i])) fail_at(source, number, "non-finite value '" + std::string(f[i + 1]) + "'");
    }
    const Eigen::Quaterniond q(v[3], v[4], v[5], v[6]);  // file order: qw qx qy qz
    if (std::abs(q.norm() - 1.0) > 1e-3)
      fail_at(source, number, "quaternion is not unit (|q| = " + std::to_string(q.norm()) + ")");
    if (!trajectory.empty() && t <= trajectory.back().t_ns)
      fail_at(source, number,
              "timestamp " + std::to_string(t) + " is not after " + std::to_string(trajectory.back().t_ns));
    trajectory.push_back(StampedPose{t, Pose3(q, Eigen::Vector3d(v[0], v[1], v[2]))});
  }
  return trajectory;
}

Trajectory read_euroc_trajectory(const std::filesystem::path& path) {
  return parse_euroc_trajectory(read_text_file(path), path);
}

void write_trajectory(const std::filesystem::path& path, const Trajectory& trajectory,
                      const std::vector<std::uint64_t>& maps, TrajectoryFormat format) {
  if (format == TrajectoryFormat::kTum) return write_tum_trajectory(path, trajectory, maps);
  write_trajectory_text(path, format_euroc_trajectory(trajectory, maps));
}

}  // namespace orbatlas
