// EuRoC sensor.yaml files: read with cv::FileStorage, written by hand in the exact
// layout of the real dataset (%YAML:1.0, plain T_BS map, flow sequences), which
// cv::FileStorage's own writer cannot produce.
#include "core/io/euroc_sensor_yaml.h"

#include <charconv>
#include <cmath>
#include <fstream>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "core/common/error.h"

namespace orbatlas {
namespace {

// Shortest text that reads back to the same double.
std::string format_number(double v) {
  char buf[32];
  const auto res = std::to_chars(buf, buf + sizeof buf, v);
  std::string s(buf, res.ptr);
  // Keep a decimal point or exponent so the value reads as a real (EuRoC style "1.0").
  if (s.find_first_of(".eEn") == std::string::npos) s += ".0";
  return s;
}

// "20" for an integral rate (as EuRoC writes it), the exact real otherwise.
std::string format_rate(double hz) {
  if (hz == std::floor(hz) && std::abs(hz) < 1e9) return std::to_string(static_cast<long long>(hz));
  return format_number(hz);
}

std::string format_list(const std::vector<double>& values) {
  std::string s = "[";
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (i > 0) s += ", ";
    s += format_number(values[i]);
  }
  return s + "]";
}

// A YAML scalar that cv::FileStorage reads back as the same string.
std::string yaml_string(const std::string& text) {
  std::string clean;
  for (const char c : text) clean += (c == '\n' || c == '\r' || c == '"' || c == '\\') ? ' ' : c;
  const bool plain = !clean.empty() && clean.find_first_of(":#{}[],&*!|>'%@`") == std::string::npos &&
                     clean.front() != ' ' && clean.back() != ' ' && clean.front() != '-';
  return plain ? clean : "\"" + clean + "\"";
}

[[noreturn]] void fail(const std::filesystem::path& yaml, const std::string& what) {
  throw DataError(yaml.string() + ": " + what);
}

cv::FileStorage open_yaml(const std::filesystem::path& yaml) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(yaml, ec)) fail(yaml, "file not found");
  cv::FileStorage fs;
  try {
    fs.open(yaml.string(), cv::FileStorage::READ | cv::FileStorage::FORMAT_YAML);
  } catch (const cv::Exception& e) {
    fail(yaml, std::string("invalid YAML: ") + e.what());
  }
  if (!fs.isOpened()) fail(yaml, "cannot open or parse");
  return fs;
}

cv::FileNode required(const cv::FileStorage& fs, const std::filesystem::path& yaml, const char* key) {
  const cv::FileNode node = fs[key];
  if (node.empty() || node.isNone()) fail(yaml, std::string("missing '") + key + "'");
  return node;
}

double read_real(const cv::FileStorage& fs, const std::filesystem::path& yaml, const char* key) {
  const cv::FileNode node = required(fs, yaml, key);
  if (!node.isReal() && !node.isInt()) fail(yaml, std::string("'") + key + "' is not a number");
  const double v = static_cast<double>(node);
  if (!std::isfinite(v)) fail(yaml, std::string("'") + key + "' is not finite");
  return v;
}

std::string read_string(const cv::FileStorage& fs, const std::filesystem::path& yaml, const char* key) {
  const cv::FileNode node = required(fs, yaml, key);
  if (!node.isString()) fail(yaml, std::string("'") + key + "' is not a string");
  return static_cast<std::string>(node);
}

std::vector<double> read_reals(const cv::FileNode& node, const std::filesystem::path& yaml, const std::string& key) {
  if (!node.isSeq()) fail(yaml, "'" + key + "' is not a list");
  std::vector<double> out;
  for (const auto& item : node) {
    if (!item.isReal() && !item.isInt()) fail(yaml, "'" + key + "' holds a non-number");
    out.push_back(static_cast<double>(item));
  }
  return out;
}

std::vector<double> read_reals(const cv::FileStorage& fs, const std::filesystem::path& yaml, const char* key,
                               std::size_t min_size, std::size_t max_size) {
  std::vector<double> v = read_reals(required(fs, yaml, key), yaml, key);
  if (v.size() < min_size || v.size() > max_size)
    fail(yaml, std::string("'") + key + "' has " + std::to_string(v.size()) + " values, expected " +
                   std::to_string(min_size) + (max_size != min_size ? " to " + std::to_string(max_size) : ""));
  return v;
}

// T_BS: {cols: 4, rows: 4, data: [16 values, row-major]}.
Pose3 read_T_BS(const cv::FileStorage& fs, const std::filesystem::path& yaml) {
  const cv::FileNode node = required(fs, yaml, "T_BS");
  if (!node.isMap()) fail(yaml, "'T_BS' is not a map {cols, rows, data}");
  const cv::FileNode rows = node["rows"], cols = node["cols"];
  if ((!rows.empty() && static_cast<int>(rows) != 4) || (!cols.empty() && static_cast<int>(cols) != 4))
    fail(yaml, "'T_BS' must be 4x4");
  const std::vector<double> d = read_reals(node["data"], yaml, "T_BS.data");
  if (d.size() != 16) fail(yaml, "'T_BS.data' has " + std::to_string(d.size()) + " values, expected 16");
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) m(r, c) = d[static_cast<std::size_t>(4 * r + c)];
  if ((m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).norm() > 1e-9) fail(yaml, "'T_BS' last row is not [0, 0, 0, 1]");
  const Eigen::Matrix3d r = m.topLeftCorner<3, 3>();
  if ((r.transpose() * r - Eigen::Matrix3d::Identity()).norm() > 1e-3 || r.determinant() < 0)
    fail(yaml, "'T_BS' rotation is not a rotation matrix");
  return Pose3::from_matrix(m);
}

void check_sensor_type(const cv::FileStorage& fs, const std::filesystem::path& yaml, const char* expected) {
  const cv::FileNode node = fs["sensor_type"];  // optional: some EuRoC-style files use camera_id instead
  if (node.empty() || !node.isString()) return;
  const std::string type = static_cast<std::string>(node);
  if (type != expected) fail(yaml, "sensor_type is '" + type + "', expected '" + expected + "'");
}

std::string T_BS_block(const Pose3& pose) {
  const Eigen::Matrix4d m = pose.matrix();
  std::string s = "T_BS:\n  cols: 4\n  rows: 4\n  data: [";
  for (int r = 0; r < 4; ++r) {
    if (r > 0) s += ",\n         ";
    for (int c = 0; c < 4; ++c) s += (c > 0 ? ", " : "") + format_number(m(r, c));
  }
  return s + "]\n";
}

void write_file(const std::filesystem::path& path, const std::string& content) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw Error("cannot create " + path.string());
  out << content;
  out.close();
  if (!out) throw Error("cannot write " + path.string());
}

}  // namespace

CameraCalibration read_camera_sensor_yaml(const std::filesystem::path& yaml) {
  const cv::FileStorage fs = open_yaml(yaml);
  check_sensor_type(fs, yaml, "camera");
  CameraCalibration cal;
  cal.T_b_c = read_T_BS(fs, yaml);
  cal.rate_hz = read_real(fs, yaml, "rate_hz");
  if (cal.rate_hz <= 0) fail(yaml, "'rate_hz' must be positive");

  const std::vector<double> res = read_reals(fs, yaml, "resolution", 2, 2);
  if (res[0] < 1 || res[1] < 1 || res[0] != std::floor(res[0]) || res[1] != std::floor(res[1]))
    fail(yaml, "'resolution' must be two positive integers");
  cal.width = static_cast<int>(res[0]);
  cal.height = static_cast<int>(res[1]);

  const cv::FileNode model_node = fs["camera_model"];
  if (!model_node.empty() && !model_node.isNone()) {
    const std::string model = read_string(fs, yaml, "camera_model");
    if (model != "pinhole") fail(yaml, "camera_model '" + model + "' is not supported (only pinhole)");
  }

  const std::vector<double> k = read_reals(fs, yaml, "intrinsics", 4, 4);
  cal.fx = k[0];
  cal.fy = k[1];
  cal.cx = k[2];
  cal.cy = k[3];
  if (cal.fx <= 0 || cal.fy <= 0) fail(yaml, "'intrinsics' focal lengths must be positive");

  const std::string distortion = read_string(fs, yaml, "distortion_model");
  if (distortion == "radial-tangential" || distortion == "radtan") {
    cal.model = CameraModel::kPinholeRadTan;
    cal.distortion = read_reals(fs, yaml, "distortion_coefficients", 4, 5);
  } else if (distortion == "equidistant") {
    cal.model = CameraModel::kKannalaBrandt;
    cal.distortion = read_reals(fs, yaml, "distortion_coefficients", 4, 4);
  } else {
    fail(yaml, "distortion_model '" + distortion + "' is not supported (radial-tangential, radtan, equidistant)");
  }
  return cal;
}

ImuCalibration read_imu_sensor_yaml(const std::filesystem::path& yaml) {
  const cv::FileStorage fs = open_yaml(yaml);
  check_sensor_type(fs, yaml, "imu");
  ImuCalibration cal;
  cal.T_b_i = read_T_BS(fs, yaml);
  cal.rate_hz = read_real(fs, yaml, "rate_hz");
  cal.gyro_noise_density = read_real(fs, yaml, "gyroscope_noise_density");
  cal.gyro_random_walk = read_real(fs, yaml, "gyroscope_random_walk");
  cal.accel_noise_density = read_real(fs, yaml, "accelerometer_noise_density");
  cal.accel_random_walk = read_real(fs, yaml, "accelerometer_random_walk");
  if (cal.rate_hz <= 0) fail(yaml, "'rate_hz' must be positive");
  if (cal.gyro_noise_density < 0 || cal.gyro_random_walk < 0 || cal.accel_noise_density < 0 ||
      cal.accel_random_walk < 0)
    fail(yaml, "IMU noise parameters must not be negative");
  return cal;
}

void write_camera_sensor_yaml(const std::filesystem::path& yaml, const CameraCalibration& calibration,
                              const std::string& comment) {
  const bool fisheye = calibration.model == CameraModel::kKannalaBrandt;
  std::string s = "%YAML:1.0\n";
  s += "# General sensor definitions.\n";
  s += "sensor_type: camera\n";
  s += "comment: " + yaml_string(comment) + "\n\n";
  s += "# Sensor extrinsics wrt. the body-frame.\n";
  s += T_BS_block(calibration.T_b_c) + "\n";
  s += "# Camera specific definitions.\n";
  s += "rate_hz: " + format_rate(calibration.rate_hz) + "\n";
  s += "resolution: [" + std::to_string(calibration.width) + ", " + std::to_string(calibration.height) + "]\n";
  s += "camera_model: pinhole\n";
  s += "intrinsics: " + format_list({calibration.fx, calibration.fy, calibration.cx, calibration.cy}) +
       " #fu, fv, cu, cv\n";
  s += std::string("distortion_model: ") + (fisheye ? "equidistant" : "radial-tangential") + "\n";
  s += "distortion_coefficients: " + format_list(calibration.distortion) + "\n";
  write_file(yaml, s);
}

void write_imu_sensor_yaml(const std::filesystem::path& yaml, const ImuCalibration& calibration) {
  std::string s = "%YAML:1.0\n";
  s += "#Default imu sensor yaml file\n";
  s += "sensor_type: imu\n";
  s += "comment: orbatlas IMU\n\n";
  s += "# Sensor extrinsics wrt. the body-frame.\n";
  s += T_BS_block(calibration.T_b_i);
  s += "rate_hz: " + format_rate(calibration.rate_hz) + "\n\n";
  s += "# inertial sensor noise model parameters (static)\n";
  s += "gyroscope_noise_density: " + format_number(calibration.gyro_noise_density) +
       "     # [ rad / s / sqrt(Hz) ]   ( gyro \"white noise\" )\n";
  s += "gyroscope_random_walk: " + format_number(calibration.gyro_random_walk) +
       "       # [ rad / s^2 / sqrt(Hz) ] ( gyro bias diffusion )\n";
  s += "accelerometer_noise_density: " + format_number(calibration.accel_noise_density) +
       "  # [ m / s^2 / sqrt(Hz) ]   ( accel \"white noise\" )\n";
  s += "accelerometer_random_walk: " + format_number(calibration.accel_random_walk) +
       "    # [ m / s^3 / sqrt(Hz) ].  ( accel bias diffusion )\n";
  write_file(yaml, s);
}

}  // namespace orbatlas
