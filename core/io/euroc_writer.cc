// Writing an EuRoC ASL dataset in the layout and csv format of the real one.
#include "core/io/euroc_writer.h"

#include <charconv>
#include <string>

#include "core/common/error.h"
#include "core/io/euroc_sensor_yaml.h"

namespace orbatlas {
namespace {

namespace fs = std::filesystem;

constexpr const char* kCameraHeader = "#timestamp [ns],filename\n";
constexpr const char* kImuHeader =
    "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],"
    "a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n";
constexpr const char* kGroundTruthHeader =
    "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z [], "
    "v_RS_R_x [m s^-1], v_RS_R_y [m s^-1], v_RS_R_z [m s^-1], b_w_RS_S_x [rad s^-1], b_w_RS_S_y [rad s^-1], "
    "b_w_RS_S_z [rad s^-1], b_a_RS_S_x [m s^-2], b_a_RS_S_y [m s^-2], b_a_RS_S_z [m s^-2]\n";

// ",<v>" with the shortest text that reads back to the same double.
void append_number(std::string& line, double v) {
  char buf[32];
  const auto res = std::to_chars(buf, buf + sizeof buf, v);
  line.push_back(',');
  line.append(buf, res.ptr);
}

void append_vec3(std::string& line, const Eigen::Vector3d& v) {
  for (int i = 0; i < 3; ++i) append_number(line, v[i]);
}

std::ofstream open_csv(const fs::path& path, const char* header) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw Error("cannot create " + path.string());
  out << header;
  return out;
}

void write_small_file(const fs::path& path, const std::string& content) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << content;
  out.close();
  if (!out) throw Error("cannot write " + path.string());
}

void check_stream(std::ofstream& out, const fs::path& path) {
  if (!out) throw Error("cannot write " + path.string());
}

}  // namespace

EurocWriter::EurocWriter(const fs::path& root, const std::vector<CameraCalibration>& cameras, const ImuCalibration& imu)
    : mav0_(root / "mav0") {
  ORBATLAS_CHECK(!cameras.empty(), "EurocWriter: at least one camera (cam0) is needed");
  std::error_code ec;
  if (fs::exists(mav0_, ec)) {
    ORBATLAS_CHECK(fs::is_directory(mav0_, ec), mav0_.string() << " exists and is not a folder");
    ORBATLAS_CHECK(fs::is_empty(mav0_, ec), "refusing to write into non-empty " << mav0_.string());
  }
  const auto make_dir = [](const fs::path& dir) {
    std::error_code mk_ec;
    fs::create_directories(dir, mk_ec);
    ORBATLAS_CHECK(!mk_ec, "cannot create " << dir.string() << ": " << mk_ec.message());
  };
  make_dir(mav0_);
  write_small_file(mav0_ / "body.yaml", "%YAML:1.0\ncomment: orbatlas simulated MAV\n");

  for (std::size_t i = 0; i < cameras.size(); ++i) {
    const std::string name = "cam" + std::to_string(i);
    const fs::path dir = mav0_ / name;
    make_dir(dir / "data");
    write_camera_sensor_yaml(dir / "sensor.yaml", cameras[i], "orbatlas simulated " + name);
    camera_csv_.push_back(open_csv(dir / "data.csv", kCameraHeader));
    last_frame_t_.push_back(-1);
  }

  make_dir(mav0_ / "imu0");
  write_imu_sensor_yaml(mav0_ / "imu0" / "sensor.yaml", imu);
  imu_csv_ = open_csv(mav0_ / "imu0" / "data.csv", kImuHeader);

  const fs::path gt_dir = mav0_ / "state_groundtruth_estimate0";
  make_dir(gt_dir);
  write_small_file(gt_dir / "sensor.yaml",
                   "%YAML:1.0\n"
                   "# General sensor definitions.\n"
                   "sensor_type: visual-inertial\n"
                   "comment: orbatlas simulation ground truth (exact body poses).\n\n"
                   "# Sensor extrinsics wrt. the body-frame.\n"
                   "T_BS:\n"
                   "  cols: 4\n"
                   "  rows: 4\n"
                   "  data: [1.0, 0.0, 0.0, 0.0,\n"
                   "         0.0, 1.0, 0.0, 0.0,\n"
                   "         0.0, 0.0, 1.0, 0.0,\n"
                   "         0.0, 0.0, 0.0, 1.0]\n");
  ground_truth_csv_ = open_csv(gt_dir / "data.csv", kGroundTruthHeader);
}

fs::path EurocWriter::image_path(int cam, TimestampNs t) const {
  ORBATLAS_CHECK(cam >= 0 && static_cast<std::size_t>(cam) < camera_csv_.size(), "EurocWriter: no camera " << cam);
  return mav0_ / ("cam" + std::to_string(cam)) / "data" / (std::to_string(t) + ".png");
}

void EurocWriter::add_frame_row(int cam, TimestampNs t) {
  ORBATLAS_CHECK(cam >= 0 && static_cast<std::size_t>(cam) < camera_csv_.size(), "EurocWriter: no camera " << cam);
  const auto c = static_cast<std::size_t>(cam);
  ORBATLAS_CHECK(camera_csv_[c].is_open(), "EurocWriter: add_frame_row after close()");
  ORBATLAS_CHECK(t > last_frame_t_[c], "EurocWriter: cam" << cam << " frame at " << t
                                                          << " ns is not after the previous one (" << last_frame_t_[c]
                                                          << " ns)");
  last_frame_t_[c] = t;
  camera_csv_[c] << t << ',' << t << ".png\n";
}

void EurocWriter::write_imu(const std::vector<ImuSample>& samples) {
  ORBATLAS_CHECK(imu_csv_.is_open(), "EurocWriter: write_imu after close()");
  std::string text;
  text.reserve(samples.size() * 128);
  for (const ImuSample& s : samples) {
    ORBATLAS_CHECK(s.t_ns > last_imu_t_, "EurocWriter: IMU sample at "
                                             << s.t_ns << " ns is not after the previous one (" << last_imu_t_
                                             << " ns)");
    last_imu_t_ = s.t_ns;
    text += std::to_string(s.t_ns);
    append_vec3(text, s.gyro);
    append_vec3(text, s.accel);
    text.push_back('\n');
  }
  imu_csv_ << text;
  check_stream(imu_csv_, mav0_ / "imu0" / "data.csv");
}

void EurocWriter::write_ground_truth(const std::vector<GroundTruthState>& states) {
  ORBATLAS_CHECK(ground_truth_csv_.is_open(), "EurocWriter: write_ground_truth after close()");
  std::string text;
  text.reserve(states.size() * 256);
  for (const GroundTruthState& s : states) {
    ORBATLAS_CHECK(s.t_ns > last_ground_truth_t_, "EurocWriter: ground truth at "
                                                      << s.t_ns << " ns is not after the previous one ("
                                                      << last_ground_truth_t_ << " ns)");
    last_ground_truth_t_ = s.t_ns;
    text += std::to_string(s.t_ns);
    append_vec3(text, s.T_w_b.t);
    const Eigen::Quaterniond& q = s.T_w_b.q;
    append_number(text, q.w());
    append_number(text, q.x());
    append_number(text, q.y());
    append_number(text, q.z());
    append_vec3(text, s.v_w);
    append_vec3(text, s.gyro_bias);
    append_vec3(text, s.accel_bias);
    text.push_back('\n');
  }
  ground_truth_csv_ << text;
  check_stream(ground_truth_csv_, mav0_ / "state_groundtruth_estimate0" / "data.csv");
}

void EurocWriter::close() {
  for (std::size_t i = 0; i < camera_csv_.size(); ++i) {
    if (!camera_csv_[i].is_open()) continue;
    camera_csv_[i].close();
    check_stream(camera_csv_[i], mav0_ / ("cam" + std::to_string(i)) / "data.csv");
  }
  if (imu_csv_.is_open()) {
    imu_csv_.close();
    check_stream(imu_csv_, mav0_ / "imu0" / "data.csv");
  }
  if (ground_truth_csv_.is_open()) {
    ground_truth_csv_.close();
    check_stream(ground_truth_csv_, mav0_ / "state_groundtruth_estimate0" / "data.csv");
  }
}

}  // namespace orbatlas
