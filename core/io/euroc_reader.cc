// Reading an EuRoC ASL dataset: the csv files of mav0/ and their sensor.yaml files.
#include "core/io/euroc_reader.h"

#include <cmath>
#include <cstdlib>
#include <limits>
#include <string>
#include <string_view>

#include "core/common/error.h"
#include "core/common/log.h"
#include "core/common/text_file.h"
#include "core/io/euroc_sensor_yaml.h"
#include "core/io/recording_paths.h"

namespace orbatlas {
namespace {

namespace fs = std::filesystem;

[[noreturn]] void fail_at(const fs::path& path, std::size_t line, const std::string& what) {
  throw DataError(path.string() + ":" + std::to_string(line) + ": " + what);
}

bool is_data_line(std::string_view text) {
  const std::string_view t = trim(text);
  return !t.empty() && t.front() != '#';
}

// Splits a csv row and checks its field count.
std::vector<std::string_view> csv_fields(const TextLine& line, const fs::path& csv, std::size_t expected) {
  std::vector<std::string_view> f = split_fields(line.text, ",", false);
  if (f.size() != expected)
    fail_at(csv, line.number,
            "expected " + std::to_string(expected) + " comma-separated fields, found " + std::to_string(f.size()));
  return f;
}

// Timestamps of a csv must strictly increase.
class TimestampOrder {
 public:
  explicit TimestampOrder(const fs::path& csv) : csv_(csv) {}
  void check(TimestampNs t, std::size_t line) {
    if (has_previous_ && t == previous_)
      fail_at(csv_, line,
              "duplicate timestamp " + std::to_string(t) + " (also on line " + std::to_string(previous_line_) + ")");
    if (has_previous_ && t < previous_)
      fail_at(csv_, line,
              "timestamp " + std::to_string(t) + " is before the previous row's " + std::to_string(previous_) +
                  " (line " + std::to_string(previous_line_) + ")");
    if (t < 0) fail_at(csv_, line, "negative timestamp " + std::to_string(t));
    has_previous_ = true;
    previous_ = t;
    previous_line_ = line;
  }

 private:
  fs::path csv_;
  bool has_previous_ = false;
  TimestampNs previous_ = 0;
  std::size_t previous_line_ = 0;
};

// `finite_only`: "nan" and "inf" refused (an IMU's reading of them is kept:
// the session drops such samples and says so, core/imu/imu_input_check.h).
Eigen::Vector3d parse_vec3(const std::vector<std::string_view>& f, std::size_t first, const fs::path& csv,
                           std::size_t line, bool finite_only = true) {
  Eigen::Vector3d v;
  for (int i = 0; i < 3; ++i) {
    v[i] = parse_double(f[first + static_cast<std::size_t>(i)], csv, line);
    if (finite_only && !std::isfinite(v[i])) fail_at(csv, line, "non-finite value");
  }
  return v;
}

// mav0/ inside `dir`, or `dir` itself when it is a mav0 folder.
fs::path find_mav0(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw DataError(dir.string() + ": dataset folder not found");
  if (fs::is_directory(dir / "mav0", ec)) return dir / "mav0";
  if (dir.filename() == "mav0" || fs::is_directory(dir / "cam0", ec)) return dir;
  throw DataError(dir.string() + ": not an EuRoC dataset (no mav0/ folder)");
}

CameraStream read_camera(const fs::path& cam_dir, EurocDataset& dataset, const RecordingConfinement& confinement) {
  const fs::path csv = cam_dir / "data.csv";
  std::error_code ec;
  if (!fs::is_regular_file(csv, ec)) throw DataError(csv.string() + ": file not found");
  CameraStream stream;
  stream.calibration = read_camera_sensor_yaml(cam_dir / "sensor.yaml");
  const fs::path image_dir = cam_dir / "data";
  TimestampOrder order(csv);
  for_each_line(csv, [&](const TextLine& line) {
    if (!is_data_line(line.text)) return;
    const auto f = csv_fields(line, csv, 2);
    const TimestampNs t = parse_int64(f[0], csv, line.number);
    order.check(t, line.number);
    if (f[1].empty()) fail_at(csv, line.number, "empty image file name");
    fs::path image = recording_file(image_dir, f[1], confinement, csv, line.number);
    if (!fs::is_regular_file(image, ec)) {
      const std::string warning = csv.string() + ":" + std::to_string(line.number) + ": image " + image.string() +
                                  " does not exist; row skipped";
      log_warn(warning);
      dataset.warnings.push_back(warning);
      return;
    }
    stream.frames.push_back(ImageFrame{t, std::move(image)});
  });
  return stream;
}

std::vector<ImuSample> read_imu_csv(const fs::path& csv) {
  std::vector<ImuSample> samples;
  TimestampOrder order(csv);
  for_each_line(csv, [&](const TextLine& line) {
    if (!is_data_line(line.text)) return;
    const auto f = csv_fields(line, csv, 7);
    ImuSample s;
    s.t_ns = parse_int64(f[0], csv, line.number);
    order.check(s.t_ns, line.number);
    s.gyro = parse_vec3(f, 1, csv, line.number, /*finite_only=*/false);
    s.accel = parse_vec3(f, 4, csv, line.number, /*finite_only=*/false);
    samples.push_back(s);
  });
  return samples;
}

}  // namespace

std::vector<GroundTruthState> read_asl_ground_truth_csv(const fs::path& csv) {
  std::vector<GroundTruthState> states;
  TimestampOrder order(csv);
  for_each_line(csv, [&](const TextLine& line) {
    if (!is_data_line(line.text)) return;
    const auto f = csv_fields(line, csv, 17);
    GroundTruthState s;
    s.t_ns = parse_int64(f[0], csv, line.number);
    order.check(s.t_ns, line.number);
    const Eigen::Vector3d p = parse_vec3(f, 1, csv, line.number);
    const double qw = parse_double(f[4], csv, line.number);
    const Eigen::Vector3d qv = parse_vec3(f, 5, csv, line.number);
    const Eigen::Quaterniond q(qw, qv.x(), qv.y(), qv.z());
    if (!std::isfinite(qw) || std::abs(q.norm() - 1.0) > 1e-3)
      fail_at(csv, line.number, "quaternion is not unit (|q| = " + std::to_string(q.norm()) + ")");
    s.T_w_b = Pose3(q, p);
    s.v_w = parse_vec3(f, 8, csv, line.number);
    s.gyro_bias = parse_vec3(f, 11, csv, line.number);
    s.accel_bias = parse_vec3(f, 14, csv, line.number);
    states.push_back(s);
  });
  return states;
}

EurocDataset read_euroc_dataset(const fs::path& dir, const EurocReadOptions& options) {
  const fs::path mav0 = find_mav0(dir);
  EurocDataset dataset;
  dataset.root = mav0.parent_path();
  std::error_code ec;

  if (!fs::is_directory(mav0 / "cam0", ec)) throw DataError((mav0 / "cam0").string() + ": folder not found");
  const RecordingConfinement confinement{options.confined ? dir : fs::path()};
  dataset.cameras.push_back(read_camera(mav0 / "cam0", dataset, confinement));
  if (fs::is_directory(mav0 / "cam1", ec)) {
    dataset.cameras.push_back(read_camera(mav0 / "cam1", dataset, confinement));
  } else if (options.require_cam1) {
    throw DataError((mav0 / "cam1").string() + ": folder not found (stereo needs cam1)");
  }

  const fs::path imu_dir = mav0 / "imu0";
  if (fs::is_directory(imu_dir, ec)) {
    dataset.imu_calibration = read_imu_sensor_yaml(imu_dir / "sensor.yaml");
    if (!fs::is_regular_file(imu_dir / "data.csv", ec))
      throw DataError((imu_dir / "data.csv").string() + ": file not found");
    dataset.imu = read_imu_csv(imu_dir / "data.csv");
  }
  if (options.require_imu && dataset.imu.empty())
    throw DataError(imu_dir.string() + ": no IMU samples (inertial use needs imu0/data.csv)");

  const fs::path gt_csv = mav0 / "state_groundtruth_estimate0" / "data.csv";
  if (fs::is_regular_file(gt_csv, ec)) dataset.ground_truth = read_asl_ground_truth_csv(gt_csv);
  return dataset;
}

std::vector<DatasetFrame> pair_stereo_frames(const EurocDataset& dataset, TimestampNs tolerance_ns) {
  if (dataset.cameras.size() < 2) throw DataError(dataset.root.string() + ": no cam1, cannot pair stereo frames");
  const auto& left = dataset.cameras[0].frames;
  const auto& right = dataset.cameras[1].frames;
  std::vector<DatasetFrame> pairs;
  std::size_t i = 0, j = 0;
  while (i < left.size() && j < right.size()) {
    const TimestampNs dt = left[i].t_ns - right[j].t_ns;
    if (std::abs(dt) <= tolerance_ns) {
      pairs.push_back(DatasetFrame{left[i].t_ns, left[i].path, right[j].path});
      ++i;
      ++j;
    } else if (dt < 0) {
      ++i;
    } else {
      ++j;
    }
  }
  return pairs;
}

void keep_time_window(std::vector<DatasetFrame>& frames, double start_s, std::optional<double> duration_s,
                      const std::filesystem::path& dataset) {
  ORBATLAS_CHECK(!frames.empty(), dataset << " has no stereo frames");
  const TimestampNs from = frames.front().t_ns + static_cast<TimestampNs>(start_s * 1e9);
  const TimestampNs to =
      duration_s ? from + static_cast<TimestampNs>(*duration_s * 1e9) : std::numeric_limits<TimestampNs>::max();
  std::erase_if(frames, [&](const DatasetFrame& f) { return f.t_ns < from || f.t_ns >= to; });
  ORBATLAS_CHECK(!frames.empty(), "no frame of " << dataset << " lies in the chosen time window");
}

}  // namespace orbatlas
