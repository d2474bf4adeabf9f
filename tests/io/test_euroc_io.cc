// EuRoC dataset writing and reading: a small synthetic dataset round trip, and the
// error paths of the reader.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>

#include "core/common/error.h"
#include "core/common/text_file.h"
#include "core/io/euroc_reader.h"
#include "core/io/euroc_sensor_yaml.h"
#include "core/io/euroc_writer.h"

namespace orbatlas {
namespace {

namespace fs = std::filesystem;

// A fresh folder per test, removed afterwards.
class TempDir {
 public:
  TempDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = fs::temp_directory_path() /
            ("orbatlas_" + std::string(info->test_suite_name()) + "_" + info->name() + "_" + std::to_string(getpid()));
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

CameraCalibration make_camera(int index) {
  CameraCalibration c;
  c.model = index == 0 ? CameraModel::kPinholeRadTan : CameraModel::kKannalaBrandt;
  c.fx = 458.654 + index;
  c.fy = 457.296 - index;
  c.cx = 367.215 + 0.125 * index;
  c.cy = 248.375;
  c.distortion = index == 0 ? std::vector<double>{-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05}
                            : std::vector<double>{-0.020476443, -0.007108226, 0.002180580, -0.001192386};
  c.width = 32;
  c.height = 24;
  c.rate_hz = 20;
  Eigen::Matrix4d m;
  m << 0.0148655429818, -0.999880929698, 0.00414029679422, -0.0216401454975, 0.999557249008, 0.0149672133247,
      0.025715529948, -0.064676986768, -0.0257744366974, 0.00375618835797, 0.999660727178, 0.00981073058949, 0, 0, 0, 1;
  c.T_b_c = Pose3::from_matrix(m);
  c.T_b_c.t.y() += 0.11 * index;
  return c;
}

ImuCalibration make_imu() {
  ImuCalibration imu;
  imu.T_b_i = Pose3(Eigen::Quaterniond(Eigen::AngleAxisd(0.1, Eigen::Vector3d(1, 2, 3).normalized())),
                    Eigen::Vector3d(0.01, -0.02, 0.03));
  imu.rate_hz = 200;
  imu.gyro_noise_density = 1.6968e-04;
  imu.gyro_random_walk = 1.9393e-05;
  imu.accel_noise_density = 2.0e-3;
  imu.accel_random_walk = 3.0e-3;
  return imu;
}

constexpr TimestampNs kT0 = 1403715273262142976;
constexpr TimestampNs kFramePeriod = 50'000'000;
constexpr TimestampNs kImuPeriod = 5'000'000;

std::vector<ImuSample> make_imu_samples(int n) {
  std::vector<ImuSample> out;
  for (int i = 0; i < n; ++i) {
    ImuSample s;
    s.t_ns = kT0 + i * kImuPeriod + (i % 3);  // not round, on purpose
    s.gyro = Eigen::Vector3d(0.1 * i, -0.0020943951023931952, 1.0 / 3.0 + i);
    s.accel = Eigen::Vector3d(9.0874956666666655, 0.13075533333333333 * i, -3.6938381666666662);
    out.push_back(s);
  }
  return out;
}

std::vector<GroundTruthState> make_ground_truth(int n) {
  std::vector<GroundTruthState> out;
  for (int i = 0; i < n; ++i) {
    GroundTruthState s;
    s.t_ns = kT0 + i * kImuPeriod;
    s.T_w_b = Pose3(Eigen::Quaterniond(Eigen::AngleAxisd(0.01 * i + 0.3, Eigen::Vector3d(0.2, -1, 0.5).normalized())),
                    Eigen::Vector3d(0.878895 + 0.001 * i, 2.1834, 0.948427 - 1e-7 * i));
    s.v_w = Eigen::Vector3d(0.00157587, 0.1 * i, -0.00231615);
    s.gyro_bias = Eigen::Vector3d(-0.00224703, 0.0215352, 0.0770299);
    s.accel_bias = Eigen::Vector3d(-0.0180115, 0.0659796, 0.0309774 * i);
    out.push_back(s);
  }
  return out;
}

void write_png(const fs::path& path, int value) {
  const cv::Mat img(24, 32, CV_8UC1, cv::Scalar(value));
  ASSERT_TRUE(cv::imwrite(path.string(), img));
}

constexpr int kFrames = 6;
constexpr int kImuSamples = 70;
constexpr int kGroundTruth = 60;

// A complete stereo-inertial dataset in `root`.
void write_dataset(const fs::path& root) {
  EurocWriter writer(root, {make_camera(0), make_camera(1)}, make_imu());
  for (int i = 0; i < kFrames; ++i) {
    const TimestampNs t = kT0 + i * kFramePeriod;
    for (int cam = 0; cam < 2; ++cam) {
      write_png(writer.image_path(cam, t), 10 * i + cam);
      writer.add_frame_row(cam, t);
    }
  }
  writer.write_imu(make_imu_samples(40));
  const auto rest = make_imu_samples(kImuSamples);
  writer.write_imu(std::vector<ImuSample>(rest.begin() + 40, rest.end()));  // appends
  writer.write_ground_truth(make_ground_truth(kGroundTruth));
  writer.close();
}

void expect_pose_near(const Pose3& a, const Pose3& b, double tol) {
  EXPECT_LT((a.t - b.t).norm(), tol);
  EXPECT_LT(a.q.angularDistance(b.q), tol);
}

void expect_camera_equal(const CameraCalibration& got, const CameraCalibration& want) {
  EXPECT_EQ(got.model, want.model);
  EXPECT_EQ(got.fx, want.fx);
  EXPECT_EQ(got.fy, want.fy);
  EXPECT_EQ(got.cx, want.cx);
  EXPECT_EQ(got.cy, want.cy);
  EXPECT_EQ(got.distortion, want.distortion);
  EXPECT_EQ(got.width, want.width);
  EXPECT_EQ(got.height, want.height);
  EXPECT_EQ(got.rate_hz, want.rate_hz);
  expect_pose_near(got.T_b_c, want.T_b_c, 1e-12);
}

// Replaces the content of a csv (header kept) with `rows`.
void rewrite_csv(const fs::path& csv, const std::string& rows) {
  std::ofstream out(csv, std::ios::trunc);
  out << "#timestamp [ns],filename\n" << rows;
}

std::string frame_row(int i) {
  const TimestampNs t = kT0 + i * kFramePeriod;
  return std::to_string(t) + "," + std::to_string(t) + ".png\n";
}

TEST(EurocIo, WriteThenReadKeepsEveryField) {
  TempDir dir;
  write_dataset(dir.path());
  const EurocDataset d = read_euroc_dataset(dir.path());

  EXPECT_EQ(d.root, dir.path());
  EXPECT_TRUE(d.warnings.empty());
  ASSERT_EQ(d.cameras.size(), 2u);
  for (int cam = 0; cam < 2; ++cam) {
    SCOPED_TRACE("cam" + std::to_string(cam));
    const CameraStream& s = d.cameras[static_cast<std::size_t>(cam)];
    expect_camera_equal(s.calibration, make_camera(cam));
    ASSERT_EQ(s.frames.size(), static_cast<std::size_t>(kFrames));
    for (int i = 0; i < kFrames; ++i) {
      const ImageFrame& f = s.frames[static_cast<std::size_t>(i)];
      EXPECT_EQ(f.t_ns, kT0 + i * kFramePeriod);
      EXPECT_EQ(f.path.filename().string(), std::to_string(f.t_ns) + ".png");
      const cv::Mat img = cv::imread(f.path.string(), cv::IMREAD_UNCHANGED);
      ASSERT_FALSE(img.empty());
      EXPECT_EQ(img.at<unsigned char>(3, 4), 10 * i + cam);
    }
  }

  ASSERT_TRUE(d.imu_calibration.has_value());
  const ImuCalibration want_imu = make_imu();
  EXPECT_EQ(d.imu_calibration->rate_hz, want_imu.rate_hz);
  EXPECT_EQ(d.imu_calibration->gyro_noise_density, want_imu.gyro_noise_density);
  EXPECT_EQ(d.imu_calibration->gyro_random_walk, want_imu.gyro_random_walk);
  EXPECT_EQ(d.imu_calibration->accel_noise_density, want_imu.accel_noise_density);
  EXPECT_EQ(d.imu_calibration->accel_random_walk, want_imu.accel_random_walk);
  expect_pose_near(d.imu_calibration->T_b_i, want_imu.T_b_i, 1e-12);

  const auto want_imu_samples = make_imu_samples(kImuSamples);
  ASSERT_EQ(d.imu.size(), want_imu_samples.size());
  for (std::size_t i = 0; i < d.imu.size(); ++i) {
    EXPECT_EQ(d.imu[i].t_ns, want_imu_samples[i].t_ns);
    EXPECT_EQ(d.imu[i].gyro, want_imu_samples[i].gyro);  // bit-exact: shortest round-trip text
    EXPECT_EQ(d.imu[i].accel, want_imu_samples[i].accel);
  }

  const auto want_gt = make_ground_truth(kGroundTruth);
  ASSERT_EQ(d.ground_truth.size(), want_gt.size());
  for (std::size_t i = 0; i < d.ground_truth.size(); ++i) {
    const GroundTruthState& g = d.ground_truth[i];
    EXPECT_EQ(g.t_ns, want_gt[i].t_ns);
    expect_pose_near(g.T_w_b, want_gt[i].T_w_b, 1e-15);
    EXPECT_EQ(g.v_w, want_gt[i].v_w);
    EXPECT_EQ(g.gyro_bias, want_gt[i].gyro_bias);
    EXPECT_EQ(g.accel_bias, want_gt[i].accel_bias);
  }

  const auto pairs = pair_stereo_frames(d);
  ASSERT_EQ(pairs.size(), static_cast<std::size_t>(kFrames));
  EXPECT_EQ(pairs[2].t_ns, kT0 + 2 * kFramePeriod);
  EXPECT_EQ(pairs[2].left, d.cameras[0].frames[2].path);
  EXPECT_EQ(pairs[2].right, d.cameras[1].frames[2].path);

  // The mav0 folder itself is accepted too.
  EXPECT_EQ(read_euroc_dataset(dir.path() / "mav0").cameras[0].frames.size(), static_cast<std::size_t>(kFrames));
}

TEST(EurocIo, WrittenFilesLookLikeEuroc) {
  TempDir dir;
  write_dataset(dir.path());
  const fs::path mav0 = dir.path() / "mav0";
  const std::string cam_yaml = read_text_file(mav0 / "cam0" / "sensor.yaml");
  EXPECT_EQ(cam_yaml.rfind("%YAML:1.0\n", 0), 0u);
  for (const char* key : {"sensor_type: camera", "T_BS:\n  cols: 4\n  rows: 4\n  data: [", "rate_hz: 20",
                          "resolution: [32, 24]", "camera_model: pinhole", "intrinsics: [458.654, 457.296",
                          "distortion_model: radial-tangential", "distortion_coefficients: [-0.28340811"})
    EXPECT_NE(cam_yaml.find(key), std::string::npos) << key;
  EXPECT_NE(read_text_file(mav0 / "cam1" / "sensor.yaml").find("distortion_model: equidistant"), std::string::npos);
  const std::string imu_yaml = read_text_file(mav0 / "imu0" / "sensor.yaml");
  for (const char* key : {"sensor_type: imu", "gyroscope_noise_density: ", "accelerometer_random_walk: "})
    EXPECT_NE(imu_yaml.find(key), std::string::npos) << key;

  const std::string cam_csv = read_text_file(mav0 / "cam0" / "data.csv");
  EXPECT_EQ(cam_csv.rfind("#timestamp [ns],filename\n" + frame_row(0), 0), 0u);
  const std::string imu_csv = read_text_file(mav0 / "imu0" / "data.csv");
  EXPECT_EQ(imu_csv.rfind("#timestamp [ns],w_RS_S_x [rad s^-1]", 0), 0u);
  const std::string gt_csv = read_text_file(mav0 / "state_groundtruth_estimate0" / "data.csv");
  const std::size_t first_row = gt_csv.find('\n') + 1;
  const std::string row = gt_csv.substr(first_row, gt_csv.find('\n', first_row) - first_row);
  EXPECT_EQ(split_fields(row, ",", false).size(), 17u);
  EXPECT_EQ(row.rfind(std::to_string(kT0) + ",", 0), 0u);  // integer ns
  EXPECT_TRUE(fs::is_regular_file(mav0 / "body.yaml"));
  EXPECT_TRUE(fs::is_regular_file(mav0 / "state_groundtruth_estimate0" / "sensor.yaml"));
}

TEST(EurocIo, WriterRefusesNonEmptyMav0) {
  TempDir dir;
  write_dataset(dir.path());
  EXPECT_THROW(EurocWriter(dir.path(), {make_camera(0)}, make_imu()), Error);
}

TEST(EurocIo, WriterRejectsOutOfOrderRows) {
  TempDir dir;
  EurocWriter writer(dir.path(), {make_camera(0)}, make_imu());
  writer.add_frame_row(0, kT0 + kFramePeriod);
  EXPECT_THROW(writer.add_frame_row(0, kT0), Error);
  EXPECT_THROW(writer.add_frame_row(1, kT0 + 2 * kFramePeriod), Error);  // no cam1
}

TEST(EurocIo, MissingImageIsSkippedWithWarning) {
  TempDir dir;
  write_dataset(dir.path());
  const fs::path cam1 = dir.path() / "mav0" / "cam1";
  fs::remove(cam1 / "data" / (std::to_string(kT0 + 3 * kFramePeriod) + ".png"));
  const EurocDataset d = read_euroc_dataset(dir.path());
  EXPECT_EQ(d.cameras[0].frames.size(), static_cast<std::size_t>(kFrames));
  ASSERT_EQ(d.cameras[1].frames.size(), static_cast<std::size_t>(kFrames - 1));
  ASSERT_EQ(d.warnings.size(), 1u);
  EXPECT_NE(d.warnings[0].find("data.csv:5"), std::string::npos) << d.warnings[0];
  EXPECT_NE(d.warnings[0].find(std::to_string(kT0 + 3 * kFramePeriod) + ".png"), std::string::npos);
  EXPECT_EQ(pair_stereo_frames(d).size(), static_cast<std::size_t>(kFrames - 1));
}

// The DataError message of reading `root`, or "" if it does not throw.
std::string read_error(const fs::path& root, const EurocReadOptions& options = {}) {
  try {
    read_euroc_dataset(root, options);
  } catch (const DataError& e) {
    return e.what();
  }
  return "";
}

TEST(EurocIo, MissingCam0IsAnError) {
  TempDir dir;
  write_dataset(dir.path());
  fs::remove_all(dir.path() / "mav0" / "cam0");
  EXPECT_NE(read_error(dir.path()).find("cam0"), std::string::npos);
}

TEST(EurocIo, MissingCsvIsAnError) {
  TempDir dir;
  write_dataset(dir.path());
  fs::remove(dir.path() / "mav0" / "cam0" / "data.csv");
  EXPECT_NE(read_error(dir.path()).find("data.csv"), std::string::npos);
}

TEST(EurocIo, NotADatasetIsAnError) {
  TempDir dir;
  EXPECT_NE(read_error(dir.path()).find("mav0"), std::string::npos);
  EXPECT_NE(read_error(dir.path() / "nowhere").find("not found"), std::string::npos);
}

TEST(EurocIo, DecreasingTimestampIsAnError) {
  TempDir dir;
  write_dataset(dir.path());
  rewrite_csv(dir.path() / "mav0" / "cam0" / "data.csv", frame_row(0) + frame_row(2) + frame_row(1));
  const std::string msg = read_error(dir.path());
  EXPECT_NE(msg.find("cam0/data.csv:4:"), std::string::npos) << msg;
  EXPECT_NE(msg.find("before"), std::string::npos) << msg;
}

TEST(EurocIo, DuplicateTimestampIsAnError) {
  TempDir dir;
  write_dataset(dir.path());
  rewrite_csv(dir.path() / "mav0" / "cam1" / "data.csv", frame_row(0) + frame_row(1) + frame_row(1));
  const std::string msg = read_error(dir.path());
  EXPECT_NE(msg.find("cam1/data.csv:4:"), std::string::npos) << msg;
  EXPECT_NE(msg.find("duplicate"), std::string::npos) << msg;
}

TEST(EurocIo, MalformedRowsAreErrors) {
  TempDir dir;
  write_dataset(dir.path());
  const fs::path csv = dir.path() / "mav0" / "cam0" / "data.csv";
  rewrite_csv(csv, frame_row(0) + "14037152733121431x4,a.png\n");
  EXPECT_NE(read_error(dir.path()).find("cam0/data.csv:3: not an integer"), std::string::npos);
  rewrite_csv(csv, frame_row(0) + frame_row(1).substr(0, 19) + "\n");
  EXPECT_NE(read_error(dir.path()).find("cam0/data.csv:3: expected 2"), std::string::npos);

  rewrite_csv(csv, frame_row(0));
  const fs::path imu = dir.path() / "mav0" / "imu0" / "data.csv";
  std::ofstream(imu, std::ios::app) << "1503715273262142976,1,2,3,4,5\n";
  const std::string msg = read_error(dir.path());
  EXPECT_NE(msg.find("imu0/data.csv:72: expected 7"), std::string::npos) << msg;
}

TEST(EurocIo, BadYamlIsADataErrorNamingTheFile) {
  TempDir dir;
  write_dataset(dir.path());
  const fs::path yaml = dir.path() / "mav0" / "cam0" / "sensor.yaml";
  std::ofstream(yaml, std::ios::trunc) << "%YAML:1.0\nT_BS: [1, 2\nrate_hz: {\n";
  const std::string msg = read_error(dir.path());
  EXPECT_NE(msg.find("cam0/sensor.yaml"), std::string::npos) << msg;

  std::ofstream(yaml, std::ios::trunc) << "%YAML:1.0\nsensor_type: camera\nrate_hz: 20\n";
  EXPECT_NE(read_error(dir.path()).find("missing 'T_BS'"), std::string::npos);
}

TEST(EurocIo, OptionalStreams) {
  TempDir dir;
  write_dataset(dir.path());
  fs::remove_all(dir.path() / "mav0" / "cam1");
  fs::remove_all(dir.path() / "mav0" / "imu0");
  fs::remove_all(dir.path() / "mav0" / "state_groundtruth_estimate0");
  const EurocDataset d = read_euroc_dataset(dir.path());
  EXPECT_EQ(d.cameras.size(), 1u);
  EXPECT_FALSE(d.imu_calibration.has_value());
  EXPECT_TRUE(d.imu.empty());
  EXPECT_TRUE(d.ground_truth.empty());
  EXPECT_THROW(pair_stereo_frames(d), DataError);
  EXPECT_NE(read_error(dir.path(), {.require_cam1 = true}).find("cam1"), std::string::npos);
  EXPECT_NE(read_error(dir.path(), {.require_imu = true}).find("imu0"), std::string::npos);
}

// An upload's lists name files inside it only (a data.csv naming
// /other/folder/X.png or ../../X.png was tracked from another folder's images).
TEST(EurocIo, AConfinedReadRefusesFilesOutsideTheFolder) {
  TempDir dir;
  write_dataset(dir.path());
  const fs::path other = dir.path().string() + "_other";  // a sibling folder: another upload's
  fs::create_directories(other);
  write_png(other / "outside.png", 7);
  const fs::path cam0 = dir.path() / "mav0" / "cam0";
  const TimestampNs t = kT0 + kFramePeriod;
  const auto row = [&](const std::string& name) { return std::to_string(t) + "," + name + "\n"; };
  const EurocReadOptions confined{.confined = true};
  // Each way out, on line 3 (the header, frame 0, then the row).
  for (const std::string& name :
       {(other / "outside.png").string(), "../../../../" + other.filename().string() + "/outside.png",
        std::string("/etc/passwd")}) {
    SCOPED_TRACE(name);
    rewrite_csv(cam0 / "data.csv", frame_row(0) + row(name));
    const std::string error = read_error(dir.path(), confined);
    EXPECT_NE(error.find("data.csv:3"), std::string::npos) << error;
    EXPECT_NE(error.find("inside its own folder"), std::string::npos) << error;
    EXPECT_EQ(read_error(dir.path()), "") << "a local recording may name any file";
  }
  // Through a link inside the folder.
  fs::create_symlink(other, cam0 / "data" / "elsewhere");
  rewrite_csv(cam0 / "data.csv", frame_row(0) + row("elsewhere/outside.png"));
  EXPECT_NE(read_error(dir.path(), confined).find("through a link"), std::string::npos);
  // Names that stay inside are read as before.
  rewrite_csv(cam0 / "data.csv", frame_row(0) + frame_row(1));
  EXPECT_EQ(read_error(dir.path(), confined), "");
  EXPECT_EQ(read_euroc_dataset(dir.path(), confined).cameras[0].frames.size(), 2u);
  fs::remove_all(other);
}

TEST(EurocIo, SensorYamlRoundTripKeepsFiveRadTanCoefficients) {
  TempDir dir;
  CameraCalibration c = make_camera(0);
  c.distortion.push_back(-1e-7);
  c.rate_hz = 27.5;
  write_camera_sensor_yaml(dir.path() / "cam.yaml", c, "test: camera #1 \"quoted\"");
  expect_camera_equal(read_camera_sensor_yaml(dir.path() / "cam.yaml"), c);
}

}  // namespace
}  // namespace orbatlas
