#include "core/io/kitti_odometry.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "core/common/error.h"
#include "core/common/text_file.h"
#include "core/io/recording_paths.h"

namespace orbatlas {
namespace {

namespace fs = std::filesystem;

// The numbers of a line, after an optional "Name:" label.
std::vector<double> numbers_of(const TextLine& line, const fs::path& path, std::string* label) {
  std::string_view text = trim(line.text);
  label->clear();
  if (const auto colon = text.find(':'); colon != std::string_view::npos) {
    *label = std::string(trim(text.substr(0, colon)));
    text = text.substr(colon + 1);
  }
  std::vector<double> values;
  for (const std::string_view field : split_fields(text, " \t", true)) {
    const double v = parse_double(field, path, line.number);
    ORBATLAS_DATA_CHECK(std::isfinite(v), path.string() << ":" << line.number << ": '" << field << "' is not finite");
    values.push_back(v);
  }
  return values;
}

// P0 and P1 of calib.txt: labelled rows, or the first two bare rows.
KittiCalibration read_calibration(const fs::path& path) {
  std::vector<std::array<double, 12>> bare;
  std::optional<std::array<double, 12>> p0, p1;
  for_each_line(path, [&](const TextLine& line) {
    if (trim(line.text).empty()) return;
    std::string label;
    const std::vector<double> v = numbers_of(line, path, &label);
    const bool projection = label.empty() || label == "P0" || label == "P1" || label == "P2" || label == "P3";
    if (!projection) return;  // Tr (velodyne to camera) and the like
    ORBATLAS_DATA_CHECK(v.size() == 12, path.string() << ":" << line.number << ": a 3x4 projection matrix has 12 "
                                                      << "numbers, not " << v.size());
    std::array<double, 12> P{};
    std::copy(v.begin(), v.end(), P.begin());
    if (label == "P0") p0 = P;
    if (label == "P1") p1 = P;
    if (label.empty()) bare.push_back(P);
  });
  if (!p0 && !bare.empty()) p0 = bare[0];
  if (!p1 && bare.size() >= 2) p1 = bare[1];
  ORBATLAS_DATA_CHECK(p0 && p1, path.string() << ": needs the projection matrices P0 and P1 (left and right camera)");
  const auto& a = *p0;
  const auto& b = *p1;
  KittiCalibration c;
  c.fx = a[0];
  c.cx = a[2];
  c.fy = a[5];
  c.cy = a[6];
  ORBATLAS_DATA_CHECK(c.fx > 0 && c.fy > 0 && c.cx > 0 && c.cy > 0,
                      path.string() << ": P0's focal lengths and principal point must be positive");
  // A rectified pair: the same intrinsics, no skew, the right camera along x.
  const double tolerance = 1e-6 * c.fx;
  ORBATLAS_DATA_CHECK(std::abs(a[1]) <= tolerance && std::abs(a[3]) <= tolerance &&
                          std::abs(b[0] - a[0]) <= tolerance && std::abs(b[2] - a[2]) <= tolerance &&
                          std::abs(b[5] - a[5]) <= tolerance && std::abs(b[6] - a[6]) <= tolerance &&
                          std::abs(b[7]) <= tolerance,
                      path.string() << ": P0 and P1 are not a rectified stereo pair (same intrinsics, P1 displaced "
                                       "along x only)");
  c.baseline_m = -b[3] / c.fx;
  ORBATLAS_DATA_CHECK(c.baseline_m > 0.0 && c.baseline_m < 10.0,
                      path.string() << ": the baseline -P1[0][3] / fx is " << c.baseline_m << " m, not in (0, 10)");
  return c;
}

}  // namespace

std::vector<TimestampNs> read_kitti_times(const std::filesystem::path& path) {
  std::vector<TimestampNs> times;
  for_each_line(path, [&](const TextLine& line) {
    const std::string_view text = trim(line.text);
    if (text.empty()) return;
    const double s = parse_double(text, path, line.number);
    ORBATLAS_DATA_CHECK(std::isfinite(s) && s >= 0.0 && s < 1e9,
                        path.string() << ":" << line.number << ": the time " << text << " s is not in [0, 1e9)");
    const TimestampNs t = s_to_ns(s);
    ORBATLAS_DATA_CHECK(times.empty() || t > times.back(), path.string() << ":" << line.number << ": the time " << text
                                                                         << " s is not after the one before");
    times.push_back(t);
  });
  ORBATLAS_DATA_CHECK(!times.empty(), path.string() << ": no time");
  return times;
}

namespace {

std::string image_name(std::size_t i) {
  char name[32];
  std::snprintf(name, sizeof name, "%06zu.png", i);
  return name;
}

}  // namespace

bool is_kitti_sequence(const std::filesystem::path& dir) {
  std::error_code ec;
  return fs::is_directory(dir / "image_0", ec) && fs::is_regular_file(dir / "times.txt", ec) &&
         fs::is_regular_file(dir / "calib.txt", ec);
}

std::filesystem::path kitti_poses_file(const std::filesystem::path& dir) {
  std::error_code ec;
  if (fs::is_regular_file(dir / "poses.txt", ec)) return dir / "poses.txt";
  const fs::path folder = fs::absolute(dir).lexically_normal();
  const fs::path name = folder.filename().empty() ? folder.parent_path().filename() : folder.filename();
  const fs::path benchmark = folder.parent_path().parent_path() / "poses" / (name.string() + ".txt");
  if (!name.empty() && fs::is_regular_file(benchmark, ec)) return benchmark;
  return {};
}

Trajectory read_kitti_poses(const std::filesystem::path& path, const std::vector<TimestampNs>& times) {
  Trajectory poses;
  for_each_line(path, [&](const TextLine& line) {
    if (trim(line.text).empty()) return;
    std::string label;
    const std::vector<double> v = numbers_of(line, path, &label);
    ORBATLAS_DATA_CHECK(label.empty() && v.size() == 12,
                        path.string() << ":" << line.number << ": a pose is 12 numbers (3x4, row by row)");
    ORBATLAS_DATA_CHECK(poses.size() < times.size(), path.string() << ":" << line.number << ": more poses than the "
                                                                   << times.size() << " times of the sequence");
    Eigen::Matrix3d R;
    R << v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10];
    ORBATLAS_DATA_CHECK((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() < 1e-3 && R.determinant() > 0,
                        path.string() << ":" << line.number << ": the 3x3 part is not a rotation");
    Eigen::Quaterniond q(R);
    q.normalize();
    poses.push_back({times[poses.size()], Pose3(q, Eigen::Vector3d(v[3], v[7], v[11]))});
  });
  ORBATLAS_DATA_CHECK(poses.size() == times.size(),
                      path.string() << ": " << poses.size() << " poses for " << times.size() << " frames");
  return poses;
}

KittiSequence read_kitti_sequence(const std::filesystem::path& dir, bool confined) {
  ORBATLAS_DATA_CHECK(is_kitti_sequence(dir),
                      dir.string() << " is not a KITTI odometry sequence (image_0/, times.txt and calib.txt)");
  KittiSequence s;
  s.root = dir;
  s.calibration = read_calibration(dir / "calib.txt");
  const std::vector<TimestampNs> times = read_kitti_times(dir / "times.txt");
  const RecordingConfinement confinement{confined ? dir : fs::path()};
  for (std::size_t i = 0; i < times.size(); ++i) {
    const int line = static_cast<int>(i + 1);
    const fs::path left = recording_file(dir, "image_0/" + image_name(i), confinement, dir / "times.txt", line);
    const fs::path right = recording_file(dir, "image_1/" + image_name(i), confinement, dir / "times.txt", line);
    std::error_code ec;
    ORBATLAS_DATA_CHECK(fs::is_regular_file(left, ec) && fs::is_regular_file(right, ec),
                        dir.string() << ": frame " << i << " (times.txt line " << line << ") has no "
                                     << (fs::is_regular_file(left, ec) ? right : left).string());
    s.frames.push_back({times[i], left, right});
  }
  const cv::Mat first = cv::imread(s.frames.front().left.string(), cv::IMREAD_UNCHANGED);
  ORBATLAS_DATA_CHECK(!first.empty(), s.frames.front().left.string() << ": cannot read the image");
  s.calibration.width = first.cols;
  s.calibration.height = first.rows;
  if (times.size() >= 2) {
    std::vector<TimestampNs> steps;
    for (std::size_t i = 1; i < times.size(); ++i) steps.push_back(times[i] - times[i - 1]);
    std::nth_element(steps.begin(), steps.begin() + static_cast<std::ptrdiff_t>(steps.size() / 2), steps.end());
    s.fps = 1.0 / ns_to_s(steps[steps.size() / 2]);
  }
  s.ground_truth_file = kitti_poses_file(dir);
  if (!s.ground_truth_file.empty()) s.ground_truth = read_kitti_poses(s.ground_truth_file, times);
  return s;
}

Trajectory read_kitti_ground_truth(const std::filesystem::path& path) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) {
    const fs::path poses = kitti_poses_file(path);
    ORBATLAS_DATA_CHECK(!poses.empty(), path.string() << ": a KITTI sequence without poses.txt (or the benchmark's "
                                                         "poses/NN.txt): no ground truth");
    return read_kitti_poses(poses, read_kitti_times(path / "times.txt"));
  }
  const fs::path beside = path.parent_path() / "times.txt";
  const fs::path benchmark = path.parent_path().parent_path() / "sequences" / path.stem() / "times.txt";
  for (const fs::path& times : {beside, benchmark})
    if (fs::is_regular_file(times, ec)) return read_kitti_poses(path, read_kitti_times(times));
  throw DataError(path.string() + ": KITTI poses have no times: there is no times.txt beside it or in " +
                  benchmark.parent_path().string() + " (give the sequence folder as the ground truth)");
}

bool looks_like_kitti_poses(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    const std::string_view text = trim(line);
    if (text.empty()) continue;
    if (text.find(',') != std::string_view::npos || text.front() == '#') return false;
    return split_fields(text, " \t", true).size() == 12;
  }
  return false;
}

std::string kitti_settings_yaml(const KittiSequence& sequence) {
  const KittiCalibration& c = sequence.calibration;
  std::ostringstream y;
  y.precision(10);
  y << "%YAML:1.0\n"
    << "# Derived from " << (sequence.root / "calib.txt").string() << " (rectified stereo, camera 0 the body)\n"
    << "File.version: \"1.0\"\n"
    << "Sensor.type: \"stereo\"\n"
    << "Camera.type: \"PinHole\"\n"
    << "Camera1.fx: " << c.fx << "\nCamera1.fy: " << c.fy << "\nCamera1.cx: " << c.cx << "\nCamera1.cy: " << c.cy
    << "\n"
    << "Camera.width: " << c.width << "\nCamera.height: " << c.height << "\n"
    << "Camera.fps: " << std::max(1.0, std::round(sequence.fps)) << "\n"
    << "Camera.RGB: 1\n"
    << "Stereo.b: " << c.baseline_m << "\n"
    << "Stereo.ThDepth: 40.0\n"
    << "ORBextractor.nFeatures: 2000\n"
    << "ORBextractor.scaleFactor: 1.2\n"
    << "ORBextractor.nLevels: 8\n"
    << "ORBextractor.iniThFAST: 20\n"
    << "ORBextractor.minThFAST: 7\n";
  return y.str();
}

}  // namespace orbatlas
