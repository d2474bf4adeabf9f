// ORB-SLAM3 v1.0 settings: the shipped EuRoC files, a fisheye file, the older
// keys, and every error path (each must name the file and the problem).
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "core/common/data_paths.h"
#include "core/common/error.h"
#include "core/io/settings.h"

namespace orbatlas {
namespace {

namespace fs = std::filesystem;

// A folder of its own under the system temp dir, removed at the end of the test.
class SettingsFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / ("orbatlas_test_settings_" + std::to_string(::getpid()) + "_" + info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }

  fs::path write(const std::string& name, const std::string& text) const {
    const fs::path path = dir_ / name;
    std::ofstream(path) << text;
    return path;
  }

  // Expects read_settings to throw an Error whose message holds the file name and every piece of `expected`.
  static void expect_error(const fs::path& path, std::initializer_list<std::string> expected) {
    try {
      (void)read_settings(path);
      ADD_FAILURE() << "no error reading " << path;
    } catch (const Error& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find(path.filename().string()), std::string::npos) << message;
      for (const std::string& piece : expected) EXPECT_NE(message.find(piece), std::string::npos) << message;
    }
  }

  fs::path dir_;
};

fs::path shipped(const std::string& name) { return shipped_config_dir() / "euroc" / name; }

const char* kMono = R"(%YAML:1.0
File.version: "1.0"
Camera.type: "PinHole"
Camera1.fx: 458.654
Camera1.fy: 457.296
Camera1.cx: 367.215
Camera1.cy: 248.375
Camera1.k1: -0.28340811
Camera1.k2: 0.07395907
Camera1.p1: 0.00019359
Camera1.p2: 1.76187114e-05
Camera.width: 752
Camera.height: 480
Camera.fps: 20
Camera.RGB: 1
)";

const char* kStereoExtrinsics3x3 = R"(Camera2.fx: 457.587
Camera2.fy: 456.134
Camera2.cx: 379.999
Camera2.cy: 255.238
Stereo.T_c1_c2: !!opencv-matrix
  rows: 3
  cols: 3
  dt: f
  data: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
)";

void expect_euroc_cam0(const CameraCalibration& c) {
  EXPECT_EQ(c.model, CameraModel::kPinholeRadTan);
  EXPECT_DOUBLE_EQ(c.fx, 458.654);
  EXPECT_DOUBLE_EQ(c.fy, 457.296);
  EXPECT_DOUBLE_EQ(c.cx, 367.215);
  EXPECT_DOUBLE_EQ(c.cy, 248.375);
  ASSERT_EQ(c.distortion.size(), 4u);
  EXPECT_DOUBLE_EQ(c.distortion[0], -0.28340811);
  EXPECT_DOUBLE_EQ(c.distortion[1], 0.07395907);
  EXPECT_DOUBLE_EQ(c.distortion[2], 0.00019359);
  EXPECT_DOUBLE_EQ(c.distortion[3], 1.76187114e-05);
  EXPECT_EQ(c.width, 752);
  EXPECT_EQ(c.height, 480);
  EXPECT_DOUBLE_EQ(c.rate_hz, 20.0);
  // T_BS of cam0/sensor.yaml: the camera x axis is (almost) the body -y axis.
  EXPECT_NEAR(c.T_b_c.t.x(), -0.0216401454975, 1e-12);
  EXPECT_NEAR(c.T_b_c.t.y(), -0.064676986768, 1e-12);
  EXPECT_NEAR(c.T_b_c.t.z(), 0.00981073058949, 1e-12);
  EXPECT_NEAR(c.T_b_c.rotation()(0, 1), -0.999880929698, 1e-8);
}

TEST(Settings, SensorTypeNamesRoundTrip) {
  for (SensorType t : {SensorType::kMonocular, SensorType::kStereo, SensorType::kMonocularInertial,
                       SensorType::kStereoInertial, SensorType::kRgbd}) {
    EXPECT_EQ(parse_sensor_type(sensor_type_name(t)), t);
  }
  EXPECT_EQ(parse_sensor_type("Stereo-Inertial"), SensorType::kStereoInertial);
  EXPECT_EQ(parse_sensor_type("monocular"), SensorType::kMonocular);
  EXPECT_EQ(parse_sensor_type("IMU_MONOCULAR"), SensorType::kMonocularInertial);
  EXPECT_EQ(parse_sensor_type("RGB-D"), SensorType::kRgbd);
  EXPECT_FALSE(parse_sensor_type("lidar").has_value());
  EXPECT_FALSE(parse_sensor_type("").has_value());
}

TEST(Settings, ShippedMono) {
  const SlamSettings s = read_settings(shipped("mono.yaml"));
  EXPECT_EQ(s.sensor, SensorType::kMonocular);
  expect_euroc_cam0(s.camera0);
  EXPECT_FALSE(s.camera1.has_value());
  EXPECT_FALSE(s.imu.has_value());
  EXPECT_TRUE(s.T_c0_c1.t.isZero());
  EXPECT_DOUBLE_EQ(s.fps, 20.0);
  EXPECT_TRUE(s.rgb);
  EXPECT_EQ(s.orb.n_features, 1000);
  EXPECT_DOUBLE_EQ(s.orb.scale_factor, 1.2);
  EXPECT_EQ(s.orb.n_levels, 8);
  EXPECT_EQ(s.orb.ini_th_fast, 20);
  EXPECT_EQ(s.orb.min_th_fast, 7);
}

TEST(Settings, ShippedStereo) {
  const SlamSettings s = read_settings(shipped("stereo.yaml"));
  EXPECT_EQ(s.sensor, SensorType::kStereo);
  EXPECT_TRUE(s.is_stereo());
  EXPECT_FALSE(s.is_inertial());
  expect_euroc_cam0(s.camera0);
  ASSERT_TRUE(s.camera1.has_value());
  const CameraCalibration& c1 = *s.camera1;
  EXPECT_DOUBLE_EQ(c1.fx, 457.587);
  EXPECT_DOUBLE_EQ(c1.fy, 456.134);
  EXPECT_DOUBLE_EQ(c1.cx, 379.999);
  EXPECT_DOUBLE_EQ(c1.cy, 255.238);
  ASSERT_EQ(c1.distortion.size(), 4u);
  EXPECT_DOUBLE_EQ(c1.distortion[0], -0.28368365);
  EXPECT_DOUBLE_EQ(c1.distortion[3], -3.55590700e-05);
  EXPECT_EQ(c1.width, 752);
  EXPECT_DOUBLE_EQ(c1.rate_hz, 20.0);
  // The right camera is ~11 cm along the left camera's x axis.
  EXPECT_NEAR(s.T_c0_c1.t.norm(), 0.110078, 1e-5);
  EXPECT_NEAR(s.T_c0_c1.t.x(), 0.110074137800478, 1e-12);
  // camera1.T_b_c = T_b_c0 * T_c1_c2 reproduces T_BS of cam1/sensor.yaml.
  EXPECT_NEAR(c1.T_b_c.t.x(), -0.0198435579556, 1e-9);
  EXPECT_NEAR(c1.T_b_c.t.y(), 0.0453689425024, 1e-9);
  EXPECT_NEAR(c1.T_b_c.t.z(), 0.00786212447038, 1e-9);
  EXPECT_NEAR(c1.T_b_c.rotation()(1, 0), 0.999598781151, 1e-8);
  EXPECT_DOUBLE_EQ(s.stereo_th_depth, 60.0);
  EXPECT_EQ(s.orb.n_features, 1200);
  EXPECT_FALSE(s.imu.has_value());
}

TEST(Settings, ShippedRgbd) {
  const SlamSettings s = read_settings(shipped("rgbd.yaml"));
  EXPECT_EQ(s.sensor, SensorType::kRgbd);
  EXPECT_TRUE(s.is_rgbd());
  EXPECT_FALSE(s.is_stereo());
  expect_euroc_cam0(s.camera0);
  EXPECT_FALSE(s.camera1.has_value());
  ASSERT_TRUE(s.rgbd.has_value());
  EXPECT_DOUBLE_EQ(s.rgbd->depth_map_factor, 5000.0);
  EXPECT_DOUBLE_EQ(s.rgbd->baseline_m, 0.08);
  EXPECT_DOUBLE_EQ(s.stereo_th_depth, 40.0);
  SlamSettings no_depth = s;
  no_depth.rgbd.reset();
  EXPECT_THROW(no_depth.check(), Error);
}

TEST(Settings, ShippedInertial) {
  for (const auto& [name, type] : {std::pair{"mono_inertial.yaml", SensorType::kMonocularInertial},
                                   std::pair{"stereo_inertial.yaml", SensorType::kStereoInertial}}) {
    SCOPED_TRACE(name);
    const SlamSettings s = read_settings(shipped(name));
    EXPECT_EQ(s.sensor, type);
    EXPECT_TRUE(s.is_inertial());
    expect_euroc_cam0(s.camera0);
    ASSERT_TRUE(s.imu.has_value());
    EXPECT_DOUBLE_EQ(s.imu->rate_hz, 200.0);
    EXPECT_DOUBLE_EQ(s.imu->gyro_noise_density, 1.6968e-04);
    EXPECT_DOUBLE_EQ(s.imu->accel_noise_density, 2.0e-3);
    EXPECT_DOUBLE_EQ(s.imu->gyro_random_walk, 1.9393e-05);
    EXPECT_DOUBLE_EQ(s.imu->accel_random_walk, 3.0e-3);
    EXPECT_TRUE(s.imu->T_b_i.t.isZero());
    EXPECT_EQ(s.camera1.has_value(), type == SensorType::kStereoInertial);
    EXPECT_EQ(s.orb.n_features, type == SensorType::kStereoInertial ? 1200 : 1000);
  }
}

TEST_F(SettingsFiles, KannalaBrandtFisheye) {
  const fs::path path = write("fisheye.yaml", R"(%YAML:1.0
File.version: "1.0"
Camera.type: "KannalaBrandt8"
Camera1.fx: 366.163
Camera1.fy: 365.631
Camera1.cx: 380.573
Camera1.cy: 225.950
Camera1.k1: -0.020476443
Camera1.k2: -0.007108226
Camera1.k3: 0.002180580
Camera1.k4: -0.001192386
Camera.width: 752
Camera.height: 480
Camera.fps: 30.0
Camera.RGB: 0
)");
  const SlamSettings s = read_settings(path);
  EXPECT_EQ(s.camera0.model, CameraModel::kKannalaBrandt);
  EXPECT_EQ(s.sensor, SensorType::kMonocular);  // no Camera2 / Stereo / IMU keys
  ASSERT_EQ(s.camera0.distortion.size(), 4u);
  EXPECT_DOUBLE_EQ(s.camera0.distortion[2], 0.002180580);
  EXPECT_DOUBLE_EQ(s.camera0.distortion[3], -0.001192386);
  EXPECT_DOUBLE_EQ(s.fps, 30.0);
  EXPECT_DOUBLE_EQ(s.camera0.rate_hz, 30.0);
  EXPECT_FALSE(s.rgb);
  EXPECT_TRUE(s.camera0.T_b_c.t.isZero());                // no IMU.T_b_c1: identity
  EXPECT_EQ(s.orb.n_features, OrbSettings{}.n_features);  // defaults when absent
}

TEST_F(SettingsFiles, SensorTypeFromHintAndFromKeys) {
  const fs::path mono = write("mono.yaml", kMono);
  EXPECT_EQ(read_settings(mono).sensor, SensorType::kMonocular);
  EXPECT_THROW(read_settings(mono, SensorType::kStereo), Error);             // no Camera2.*
  EXPECT_THROW(read_settings(mono, SensorType::kMonocularInertial), Error);  // no IMU.*
  EXPECT_THROW(read_settings(mono, SensorType::kRgbd), Error);               // no RGBD.DepthMapFactor
  const fs::path rgbd = write("rgbd.yaml", std::string(kMono) + "RGBD.DepthMapFactor: 1000.0\nStereo.b: 0.05\n");
  EXPECT_EQ(read_settings(rgbd).sensor, SensorType::kRgbd);  // from the key
  EXPECT_DOUBLE_EQ(read_settings(rgbd).rgbd->depth_map_factor, 1000.0);

  const std::string stereo = std::string(kMono) + R"(Camera2.fx: 457.587
Camera2.fy: 456.134
Camera2.cx: 379.999
Camera2.cy: 255.238
Stereo.T_c1_c2: !!opencv-matrix
  rows: 4
  cols: 4
  dt: f
  data: [1.0, 0.0, 0.0, 0.11, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0]
)";
  const fs::path stereo_path = write("stereo.yaml", stereo);
  const SlamSettings s = read_settings(stereo_path);
  EXPECT_EQ(s.sensor, SensorType::kStereo);
  ASSERT_TRUE(s.camera1.has_value());
  EXPECT_EQ(s.camera1->distortion, std::vector<double>(4, 0.0));  // no Camera2.k1: rectified
  EXPECT_NEAR(s.T_c0_c1.t.x(), 0.11, 1e-7);                       // float matrix accepted
  EXPECT_EQ(read_settings(stereo_path, SensorType::kMonocular).sensor, SensorType::kMonocular);

  const fs::path typed = write("typed.yaml", stereo + "Sensor.type: \"mono\"\n");
  EXPECT_EQ(read_settings(typed, SensorType::kStereo).sensor, SensorType::kMonocular);  // the file wins

  const std::string inertial = stereo + R"(IMU.T_b_c1: !!opencv-matrix
  rows: 4
  cols: 4
  dt: d
  data: [0.0, -1.0, 0.0, 0.1, 1.0, 0.0, 0.0, 0.2, 0.0, 0.0, 1.0, 0.3, 0.0, 0.0, 0.0, 1.0]
IMU.NoiseGyro: 1.7e-4
IMU.NoiseAcc: 2.0e-3
IMU.GyroWalk: 1.9e-5
IMU.AccWalk: 3.0e-3
IMU.Frequency: 200
)";
  const SlamSettings si = read_settings(write("inertial.yaml", inertial));
  EXPECT_EQ(si.sensor, SensorType::kStereoInertial);
  EXPECT_NEAR(si.camera0.T_b_c.t.y(), 0.2, 1e-12);
  // camera1.T_b_c = T_b_c0 * T_c1_c2: 0.11 along camera x = body y.
  EXPECT_NEAR(si.camera1->T_b_c.t.x(), 0.1, 1e-12);
  EXPECT_NEAR(si.camera1->T_b_c.t.y(), 0.31, 1e-7);  // T_c1_c2 is float here
}

TEST_F(SettingsFiles, OlderUnversionedKeys) {
  const fs::path path = write("v0.yaml", R"(%YAML:1.0
Camera.type: "PinHole"
Camera.fx: 458.654
Camera.fy: 457.296
Camera.cx: 367.215
Camera.cy: 248.375
Camera.k1: -0.28340811
Camera.k2: 0.07395907
Camera.p1: 0.00019359
Camera.p2: 1.76187114e-05
Camera.k3: 0.0
Camera.width: 752
Camera.height: 480
Camera.fps: 20.0
Camera.RGB: 1
Tbc: !!opencv-matrix
  rows: 4
  cols: 4
  dt: f
  data: [1.0, 0.0, 0.0, 0.5, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0]
IMU.NoiseGyro: 1.7e-4
IMU.NoiseAcc: 2.0e-3
IMU.GyroWalk: 1.9e-5
IMU.AccWalk: 3.0e-3
IMU.Frequency: 200
)");
  const SlamSettings s = read_settings(path);
  EXPECT_EQ(s.sensor, SensorType::kMonocularInertial);
  EXPECT_DOUBLE_EQ(s.camera0.fx, 458.654);
  EXPECT_EQ(s.camera0.distortion.size(), 5u);
  EXPECT_NEAR(s.camera0.T_b_c.t.x(), 0.5, 1e-7);
}

TEST_F(SettingsFiles, RectifiedStereoBaseline) {
  const SlamSettings s = read_settings(write("rectified.yaml", std::string(kMono) + "Stereo.b: 0.11\n"));
  EXPECT_EQ(s.sensor, SensorType::kStereo);
  ASSERT_TRUE(s.camera1.has_value());
  EXPECT_DOUBLE_EQ(s.camera1->fx, s.camera0.fx);
  EXPECT_DOUBLE_EQ(s.T_c0_c1.t.x(), 0.11);
}

TEST_F(SettingsFiles, MissingFile) { expect_error(dir_ / "absent.yaml", {"not found"}); }

TEST_F(SettingsFiles, MalformedYaml) {
  expect_error(write("broken.yaml", "%YAML:1.0\nCamera1.fx: [1.0, 2.0\nCamera1.fy: : :\n"), {"malformed YAML"});
}

TEST_F(SettingsFiles, MissingFx) {
  std::string text = kMono;
  text.erase(text.find("Camera1.fx"), text.find("Camera1.fy") - text.find("Camera1.fx"));
  expect_error(write("no_fx.yaml", text), {"Camera1.fx", "missing"});
}

TEST_F(SettingsFiles, ExtrinsicsMustBe4x4) {
  expect_error(write("t3x3.yaml", std::string(kMono) + kStereoExtrinsics3x3), {"Stereo.T_c1_c2", "4x4", "3x3"});
}

// A matrix declaring a huge shape is refused before OpenCV allocates it (found by
// fuzz_settings: "rows: 100000000" asked for 64 GiB).
TEST_F(SettingsFiles, AMatrixOfAHugeDeclaredShapeIsRefusedBeforeItIsRead) {
  std::string text = std::string(kMono) + kStereoExtrinsics3x3;
  text.replace(text.find("rows: 3"), 7, "rows: 100000000");
  text.replace(text.find("cols: 3"), 7, "cols: 80000");
  expect_error(write("huge.yaml", text), {"Stereo.T_c1_c2", "4x4", "100000000x80000"});
}

// Text on which OpenCV's YAML reader never returns (found by fuzz_settings):
// refused before it is read, naming the line; a "---" document start and
// negative numbers at the start of a matrix's continued data still read.
TEST(Settings, TextOpenCvWouldNeverFinishReadingIsRefused) {
  try {
    read_settings_text("%YAML:1.0\n-----0\n-s--\ni", "inline");
    ADD_FAILURE() << "read";
  } catch (const DataError& e) {
    EXPECT_NE(std::string(e.what()).find("inline: malformed YAML: line 2: expected \"Key: value\""), std::string::npos)
        << e.what();
  }
  for (const char* hang : {"%YAML:1.0\n C:A\n:A--\n0", "%YAML:1.0\nA: 1\n C: 2\n", "%YAML:1.0\nA: [1, x]\n"}) {
    std::string error = "read without an error";
    try {
      read_settings_text(hang, "inline");
    } catch (const DataError& e) {
      error = e.what();
    }
    EXPECT_NE(error.find("inline: malformed YAML: line "), std::string::npos) << error;
  }
  // Text on which OpenCV's reader throws std::length_error, not its own exception.
  try {
    read_settings_text("%YAML:1.\n  c:4\n  :", "inline");
    ADD_FAILURE() << "read";
  } catch (const DataError& e) {
    EXPECT_NE(std::string(e.what()).find("inline: malformed YAML"), std::string::npos) << e.what();
  }
  std::string text = std::string(kMono) + kStereoExtrinsics3x3;
  text.replace(text.find("%YAML:1.0\n"), 10, "%YAML:1.0\n---\n");
  std::string error = "read without an error";
  try {
    read_settings_text(text, "inline");
  } catch (const DataError& e) {
    error = e.what();
  }
  EXPECT_NE(error.find("must be a 4x4 matrix, got 3x3"), std::string::npos) << error;  // read, then judged
}

TEST_F(SettingsFiles, InvalidValues) {
  const auto with = [&](const std::string& name, const std::string& from, const std::string& to) {
    std::string text = kMono;
    text.replace(text.find(from), from.size(), to);
    return write(name, text);
  };
  expect_error(with("fx.yaml", "Camera1.fx: 458.654", "Camera1.fx: -458.654"), {"Camera1.fx", "positive"});
  expect_error(with("fx_text.yaml", "Camera1.fx: 458.654", "Camera1.fx: \"big\""), {"Camera1.fx", "number"});
  expect_error(with("width.yaml", "Camera.width: 752", "Camera.width: 0"), {"Camera.width", "positive"});
  expect_error(with("fps.yaml", "Camera.fps: 20", "Camera.fps: 0"), {"Camera.fps", "positive"});
  expect_error(with("type.yaml", "\"PinHole\"", "\"Rational\""), {"Camera.type", "Rational"});
  expect_error(with("version.yaml", "\"1.0\"", "\"2.0\""), {"File.version"});
  expect_error(with("p2.yaml", "Camera1.p2: 1.76187114e-05", ""), {"Camera1.p2", "missing"});
  expect_error(with("sensor.yaml", "Camera.RGB: 1", "Camera.RGB: 1\nSensor.type: \"lidar\""), {"Sensor.type", "lidar"});
  expect_error(with("depth.yaml", "Camera.RGB: 1", "Camera.RGB: 1\nSensor.type: \"rgbd\""),
               {"RGBD.DepthMapFactor", "missing"});
  expect_error(with("rgb.yaml", "Camera.RGB: 1", "Camera.RGB: 3"), {"Camera.RGB"});
  expect_error(with("orb.yaml", "Camera.RGB: 1", "Camera.RGB: 1\nORBextractor.scaleFactor: 1.0"),
               {"ORBextractor.scaleFactor"});
  expect_error(with("kb.yaml", "\"PinHole\"", "\"KannalaBrandt8\""), {"Camera1.k3", "missing"});
  // An inertial sensor needs the camera-IMU extrinsics.
  expect_error(with("imu.yaml", "Camera.RGB: 1", "Camera.RGB: 1\nSensor.type: \"mono_inertial\"\nIMU.Frequency: 200"),
               {"IMU.T_b_c1", "missing"});
}

TEST_F(SettingsFiles, ExtrinsicsMustBeRigid) {
  expect_error(write("scaled.yaml", std::string(kMono) + R"(IMU.T_b_c1: !!opencv-matrix
  rows: 4
  cols: 4
  dt: d
  data: [2.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0]
)"),
               {"IMU.T_b_c1", "rigid"});
  expect_error(write("scalar.yaml", std::string(kMono) + "IMU.T_b_c1: 1.0\n"), {"IMU.T_b_c1", "4x4"});
}

TEST(Settings, CheckRejectsIncompleteSettings) {
  SlamSettings s = read_settings(shipped("stereo_inertial.yaml"));
  EXPECT_NO_THROW(s.check());
  SlamSettings no_imu = s;
  no_imu.imu.reset();
  EXPECT_THROW(no_imu.check(), Error);
  SlamSettings no_right = s;
  no_right.camera1.reset();
  EXPECT_THROW(no_right.check(), Error);
  SlamSettings bad_fx = s;
  bad_fx.camera0.fx = 0;
  EXPECT_THROW(bad_fx.check(), Error);
  SlamSettings mono = s;
  mono.sensor = SensorType::kMonocular;
  mono.camera1.reset();
  mono.imu.reset();
  EXPECT_NO_THROW(mono.check());
}

}  // namespace
}  // namespace orbatlas
