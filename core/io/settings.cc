// ORB-SLAM3 settings files (File.version "1.0", with a fallback to the older
// unversioned keys), read through cv::FileStorage. Every accepted key: docs/settings.md.
#include "core/io/settings.h"

#include <Eigen/Core>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <iterator>
#include <string_view>
#include <opencv2/core.hpp>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/camera/camera_factory.h"
#include "core/io/settings_shape.h"
#include "core/common/error.h"

namespace orbatlas {
namespace {

std::string number_text(double v) {
  std::ostringstream out;
  out << v;
  return out.str();
}

// OpenCV's message without its trailing newline.
std::string opencv_message(const cv::Exception& e) {
  std::string m = e.what();
  while (!m.empty() && (m.back() == '\n' || m.back() == ' ')) m.pop_back();
  return m;
}

// cv::FileStorage only parses YAML that starts with the "%YAML:1.0" directive.
std::string missing_directive_hint(const std::string& text) {
  return text.rfind("%YAML", 0) == 0 ? "" : " (the text must start with the line %YAML:1.0)";
}

std::string file_start(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::string first(5, '\0');
  in.read(first.data(), 5);
  return first;
}

// The open settings (a file, or text in memory): typed access to its keys, and
// errors naming the source and key.
class SettingsFile {
 public:
  explicit SettingsFile(const std::filesystem::path& path) : label_(path.string()) {
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) throw DataError(label_ + ": settings file not found");
    if (!std::filesystem::is_regular_file(path, ec)) throw DataError(label_ + ": not a regular file");
    {
      std::ifstream in(path, std::ios::binary);
      check_settings_shape(std::string(std::istreambuf_iterator<char>(in), {}), label_);
    }
    open(path.string(), cv::FileStorage::READ | cv::FileStorage::FORMAT_YAML, missing_directive_hint(file_start(path)));
  }
  // YAML text parsed in memory (no file is written).
  SettingsFile(const std::string& text, std::string label) : label_(std::move(label)) {
    if (text.empty()) throw DataError(label_ + ": the settings text is empty");
    check_settings_shape(text, label_);
    open(text, cv::FileStorage::READ | cv::FileStorage::MEMORY | cv::FileStorage::FORMAT_YAML,
         missing_directive_hint(text));
  }

  const std::string& label() const { return label_; }

  [[noreturn]] void fail(const std::string& key, const std::string& what) const {
    throw DataError(label_ + ": key '" + key + "' " + what);
  }

  bool has(const std::string& key) const { return std::find(keys_.begin(), keys_.end(), key) != keys_.end(); }

  std::vector<std::string> keys_with_prefix(const std::string& prefix) const {
    std::vector<std::string> out;
    for (const std::string& k : keys_)
      if (k.rfind(prefix, 0) == 0) out.push_back(k);
    return out;
  }

  bool has_prefix(const std::string& prefix) const {
    return std::any_of(keys_.begin(), keys_.end(), [&](const std::string& k) { return k.rfind(prefix, 0) == 0; });
  }

  cv::FileNode node(const std::string& key) const {
    if (!has(key)) fail(key, "is missing");
    return fs_[key];
  }

  double real(const std::string& key) const {
    const cv::FileNode n = node(key);
    if (!n.isReal() && !n.isInt()) fail(key, "must be a number");
    const double v = static_cast<double>(n);
    if (!std::isfinite(v)) fail(key, "must be finite");
    return v;
  }

  double positive(const std::string& key) const {
    const double v = real(key);
    if (!(v > 0)) fail(key, "must be positive, got " + number_text(v));
    return v;
  }

  int integer(const std::string& key) const {
    const double v = real(key);
    if (v != std::floor(v) || std::abs(v) > 1e9) fail(key, "must be an integer");
    return static_cast<int>(v);
  }

  int positive_integer(const std::string& key) const {
    const int v = integer(key);
    if (v <= 0) fail(key, "must be positive, got " + std::to_string(v));
    return v;
  }

  std::string text(const std::string& key) const {
    const cv::FileNode n = node(key);
    if (!n.isString()) fail(key, "must be a string");
    return static_cast<std::string>(n);
  }

  // A 4x4 !!opencv-matrix holding a rigid transform (float or double).
  Pose3 transform(const std::string& key) const {
    const cv::FileNode n = node(key);
    if (!n.isMap()) fail(key, "must be a 4x4 !!opencv-matrix");
    // Its declared shape first: OpenCV allocates rows x cols before it reads the
    // data, so "rows: 100000000" would take gigabytes (found by fuzz_settings).
    const cv::FileNode rows = n["rows"], cols = n["cols"];
    if (!rows.isInt() || !cols.isInt()) fail(key, "must be a 4x4 !!opencv-matrix (rows: 4, cols: 4)");
    if (static_cast<int>(rows) != 4 || static_cast<int>(cols) != 4)
      fail(key, "must be a 4x4 matrix, got " + std::to_string(static_cast<int>(rows)) + "x" +
                    std::to_string(static_cast<int>(cols)));
    cv::Mat m;
    try {
      n >> m;
    } catch (const cv::Exception& e) {
      fail(key, "is not a readable !!opencv-matrix: " + opencv_message(e));
    }
    if (m.empty()) fail(key, "must be a 4x4 !!opencv-matrix");
    if (m.rows != 4 || m.cols != 4 || m.channels() != 1) {
      fail(key, "must be a 4x4 matrix, got " + std::to_string(m.rows) + "x" + std::to_string(m.cols) +
                    (m.channels() != 1 ? " with " + std::to_string(m.channels()) + " channels" : ""));
    }
    cv::Mat md;
    m.convertTo(md, CV_64F);
    Eigen::Matrix4d e;
    for (int r = 0; r < 4; ++r) {
      for (int c = 0; c < 4; ++c) e(r, c) = md.at<double>(r, c);
    }
    if (!e.allFinite()) fail(key, "must hold finite numbers");
    if ((e.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-6) {
      fail(key, "must have [0, 0, 0, 1] as its last row");
    }
    const Eigen::Matrix3d r = e.topLeftCorner<3, 3>();
    if ((r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-4 || r.determinant() < 0) {
      fail(key, "is not a rigid transform (its rotation is not orthonormal)");
    }
    return Pose3::from_matrix(e);
  }

 private:
  void open(const std::string& source, int flags, const std::string& hint) {
    try {
      fs_.open(source, flags);
    } catch (const cv::Exception& e) {
      throw DataError(label_ + ": malformed YAML" + hint + ": " + opencv_message(e));
    } catch (const std::length_error&) {
      // OpenCV's reader lets this one through on some malformed text (found by fuzz_settings).
      throw DataError(label_ + ": malformed YAML" + hint + " (a value OpenCV's reader cannot hold)");
    }
    if (!fs_.isOpened()) throw DataError(label_ + ": cannot open or parse as YAML" + hint);
    try {
      for (const cv::FileNode& node : fs_.root()) {
        if (!node.isNone()) keys_.push_back(node.name());
      }
    } catch (const cv::Exception& e) {
      throw DataError(label_ + ": malformed YAML: " + opencv_message(e));
    }
  }

  std::string label_;
  cv::FileStorage fs_;
  std::vector<std::string> keys_;  // top-level keys ("Camera1.fx", ...)
};

struct Reader {
  const SettingsFile& file;
  bool v1;  // File.version "1.0"; else the older keys (Camera.fx, Tbc, ThDepth, Camera.bf)

  // Camera1.* (index 0) or Camera2.* (index 1).
  std::string camera_prefix(int index) const {
    if (index == 1) return "Camera2.";
    return v1 ? "Camera1." : "Camera.";
  }

  double real_or(const std::string& key, double fallback) const { return file.has(key) ? file.real(key) : fallback; }
  double positive_or(const std::string& key, double fallback) const {
    return file.has(key) ? file.positive(key) : fallback;
  }
  int positive_integer_or(const std::string& key, int fallback) const {
    return file.has(key) ? file.positive_integer(key) : fallback;
  }

  CameraModel camera_model() const {
    if (!file.has("Camera.type") && !v1) return CameraModel::kPinholeRadTan;
    const std::string type = file.text("Camera.type");
    if (type == "PinHole") return CameraModel::kPinholeRadTan;
    if (type == "KannalaBrandt8") return CameraModel::kKannalaBrandt;
    file.fail("Camera.type", "'" + type + "' is not supported (PinHole or KannalaBrandt8)");
  }

  CameraCalibration camera(int index, CameraModel model) const {
    const std::string p = camera_prefix(index);
    CameraCalibration c;
    c.model = model;
    c.fx = file.positive(p + "fx");
    c.fy = file.positive(p + "fy");
    c.cx = file.real(p + "cx");
    c.cy = file.real(p + "cy");
    if (model == CameraModel::kKannalaBrandt) {
      c.distortion = {file.real(p + "k1"), file.real(p + "k2"), file.real(p + "k3"), file.real(p + "k4")};
    } else if (file.has(p + "k1")) {
      c.distortion = {file.real(p + "k1"), file.real(p + "k2"), file.real(p + "p1"), file.real(p + "p2")};
      if (file.has(p + "k3")) c.distortion.push_back(file.real(p + "k3"));
    } else {
      c.distortion = {0.0, 0.0, 0.0, 0.0};  // ORB-SLAM3: no coefficients = rectified images
    }
    c.width = file.positive_integer("Camera.width");
    c.height = file.positive_integer("Camera.height");
    return c;
  }

  SensorType sensor(std::optional<SensorType> hint) const {
    if (file.has("Sensor.type")) {
      const std::string name = file.text("Sensor.type");
      const auto type = parse_sensor_type(name);
      if (!type)
        file.fail("Sensor.type", "'" + name + "' is not one of mono, stereo, mono_inertial, stereo_inertial, rgbd");
      return *type;
    }
    if (hint) return *hint;
    if (file.has("RGBD.DepthMapFactor") || (!v1 && file.has("DepthMapFactor"))) return SensorType::kRgbd;
    const bool stereo = file.has_prefix("Camera2.") || file.has_prefix("Stereo.") || (!v1 && file.has("Camera.bf"));
    const bool inertial = file.has_prefix("IMU.") || (!v1 && file.has("Tbc"));
    if (stereo) return inertial ? SensorType::kStereoInertial : SensorType::kStereo;
    return inertial ? SensorType::kMonocularInertial : SensorType::kMonocular;
  }
};

bool is_version_1(const SettingsFile& file) {
  if (!file.has("File.version")) return false;
  const cv::FileNode n = file.node("File.version");
  if (n.isString() && static_cast<std::string>(n) == "1.0") return true;
  if ((n.isReal() || n.isInt()) && static_cast<double>(n) == 1.0) return true;
  file.fail("File.version", "is not supported (only \"1.0\", or no File.version for the older keys)");
}

SlamSettings read(const SettingsFile& file, std::optional<SensorType> hint) {
  const Reader in{file, is_version_1(file)};
  for (const char* key : {"Camera.newWidth", "Camera.newHeight"}) {
    if (file.has(key)) file.fail(key, "is not supported: resize the images and scale the calibration instead");
  }

  SlamSettings s;
  s.sensor = in.sensor(hint);
  const CameraModel model = in.camera_model();
  s.fps = in.positive_or("Camera.fps", s.fps);
  if (file.has("Camera.RGB")) {
    const int rgb = file.integer("Camera.RGB");
    if (rgb != 0 && rgb != 1) file.fail("Camera.RGB", "must be 0 (BGR) or 1 (RGB)");
    s.rgb = rgb == 1;
  }
  s.camera0 = in.camera(0, model);
  s.camera0.rate_hz = s.fps;

  const std::string t_b_c_key = (in.v1 || !file.has("Tbc")) ? "IMU.T_b_c1" : "Tbc";
  if (file.has(t_b_c_key) || s.is_inertial()) s.camera0.T_b_c = file.transform(t_b_c_key);

  const std::string th_depth_key = (in.v1 || !file.has("ThDepth")) ? "Stereo.ThDepth" : "ThDepth";
  s.stereo_th_depth = in.positive_or(th_depth_key, s.stereo_th_depth);

  if (s.is_stereo()) {
    CameraCalibration c1;
    if (file.has("Camera2.fx")) {
      c1 = in.camera(1, model);
      s.T_c0_c1 = file.transform("Stereo.T_c1_c2");
    } else if (file.has("Stereo.b") || (!in.v1 && file.has("Camera.bf"))) {
      // Rectified stereo: both cameras share the intrinsics, camera 1 sits `b` along x.
      const double b = file.has("Stereo.b") ? file.positive("Stereo.b") : file.positive("Camera.bf") / s.camera0.fx;
      c1 = s.camera0;
      s.T_c0_c1 = Pose3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(b, 0, 0));
    } else {
      file.fail("Camera2.fx",
                "is missing: a stereo sensor needs Camera2.* and Stereo.T_c1_c2 "
                "(or Stereo.b for rectified images)");
    }
    c1.rate_hz = s.fps;
    c1.T_b_c = s.camera0.T_b_c * s.T_c0_c1;
    s.camera1 = c1;
  }

  if (s.is_rgbd()) {
    RgbdCalibration rgbd;
    rgbd.depth_map_factor =
        file.positive(in.v1 || !file.has("DepthMapFactor") ? "RGBD.DepthMapFactor" : "DepthMapFactor");
    rgbd.baseline_m =
        file.has("Stereo.b") || in.v1 ? file.positive("Stereo.b") : file.positive("Camera.bf") / s.camera0.fx;
    s.rgbd = rgbd;
  }

  if (s.is_inertial()) {
    ImuCalibration imu;
    imu.rate_hz = file.positive("IMU.Frequency");
    imu.gyro_noise_density = file.positive("IMU.NoiseGyro");
    imu.accel_noise_density = file.positive("IMU.NoiseAcc");
    imu.gyro_random_walk = file.positive("IMU.GyroWalk");
    imu.accel_random_walk = file.positive("IMU.AccWalk");
    imu.gyro_range = in.positive_or("IMU.GyroRange", 0.0);
    imu.accel_range = in.positive_or("IMU.AccRange", 0.0);
    s.imu = imu;
  }

  s.orb.n_features = in.positive_integer_or("ORBextractor.nFeatures", s.orb.n_features);
  s.orb.scale_factor = in.positive_or("ORBextractor.scaleFactor", s.orb.scale_factor);
  s.orb.n_levels = in.positive_integer_or("ORBextractor.nLevels", s.orb.n_levels);
  s.orb.ini_th_fast = in.positive_integer_or("ORBextractor.iniThFAST", s.orb.ini_th_fast);
  s.orb.min_th_fast = in.positive_integer_or("ORBextractor.minThFAST", s.orb.min_th_fast);
  if (!(s.orb.scale_factor > 1.0)) file.fail("ORBextractor.scaleFactor", "must be greater than 1");
  if (s.orb.min_th_fast > s.orb.ini_th_fast) file.fail("ORBextractor.minThFAST", "must not exceed iniThFAST");
  for (const std::string& key : file.keys_with_prefix("Orbatlas.")) s.orbatlas[key.substr(9)] = file.real(key);
  return s;
}

void check_camera(const char* which, const CameraCalibration& c) {
  try {
    check_calibration(c);
  } catch (const Error& e) {
    throw_error(std::string(which) + ": " + e.what());
  }
}

}  // namespace

void SlamSettings::check() const {
  check_camera("camera0", camera0);
  ORBATLAS_CHECK(std::isfinite(fps) && fps > 0, "settings: fps must be positive, got " << fps);
  ORBATLAS_CHECK(stereo_th_depth > 0, "settings: stereo_th_depth must be positive, got " << stereo_th_depth);
  if (is_stereo()) {
    ORBATLAS_CHECK(camera1.has_value(), "settings: a " << sensor_type_name(sensor) << " sensor needs camera1");
    check_camera("camera1", *camera1);
    ORBATLAS_CHECK(T_c0_c1.t.norm() > 0, "settings: the stereo baseline (T_c0_c1 translation) is zero");
  }
  if (is_rgbd()) {
    ORBATLAS_CHECK(rgbd.has_value(), "settings: an rgbd sensor needs RGBD.DepthMapFactor and Stereo.b");
    ORBATLAS_CHECK(std::isfinite(rgbd->depth_map_factor) && rgbd->depth_map_factor > 0 &&
                       std::isfinite(rgbd->baseline_m) && rgbd->baseline_m > 0,
                   "settings: the depth map factor and the virtual baseline must be positive");
  }
  if (is_inertial()) {
    ORBATLAS_CHECK(imu.has_value(), "settings: a " << sensor_type_name(sensor) << " sensor needs the IMU calibration");
    ORBATLAS_CHECK(imu->rate_hz > 0, "settings: IMU rate must be positive, got " << imu->rate_hz);
    ORBATLAS_CHECK(imu->gyro_noise_density > 0 && imu->accel_noise_density > 0 && imu->gyro_random_walk > 0 &&
                       imu->accel_random_walk > 0,
                   "settings: IMU noise densities and random walks must be positive");
  }
  // Upper bounds far above any real use, so that a typo is an error here and
  // not an allocation failure at the first frame.
  for (const CameraCalibration* c : {&camera0, camera1 ? &*camera1 : nullptr}) {
    if (c)
      ORBATLAS_CHECK(
          c->width <= kMaxImageSide && c->height <= kMaxImageSide,
          "settings: images of at most " << kMaxImageSide << " pixels a side, got " << c->width << "x" << c->height);
  }
  ORBATLAS_CHECK(fps <= 1000, "settings: fps must be at most 1000, got " << fps);
  ORBATLAS_CHECK(orb.n_features > 0 && orb.n_features <= kMaxOrbFeatures,
                 "settings: ORB n_features must be 1.." << kMaxOrbFeatures << ", got " << orb.n_features);
  ORBATLAS_CHECK(orb.scale_factor > 1.0 && orb.scale_factor <= 2.0,
                 "settings: ORB scale_factor must be in (1, 2], got " << orb.scale_factor);
  ORBATLAS_CHECK(orb.n_levels > 0 && orb.n_levels <= 16, "settings: ORB n_levels must be 1..16, got " << orb.n_levels);
  ORBATLAS_CHECK(orb.ini_th_fast <= 255, "settings: ORB iniThFAST must be at most 255, got " << orb.ini_th_fast);
  ORBATLAS_CHECK(orb.min_th_fast > 0 && orb.min_th_fast <= orb.ini_th_fast,
                 "settings: ORB FAST thresholds must satisfy 0 < min_th_fast <= ini_th_fast, got "
                     << orb.min_th_fast << " and " << orb.ini_th_fast);
}

namespace {

SlamSettings read_checked(const SettingsFile& file, std::optional<SensorType> sensor_hint) {
  SlamSettings s = read(file, sensor_hint);
  try {
    s.check();
  } catch (const Error& e) {
    throw DataError(file.label() + ": " + e.what());
  }
  return s;
}

}  // namespace

SlamSettings read_settings(const std::filesystem::path& yaml, std::optional<SensorType> sensor_hint) {
  return read_checked(SettingsFile(yaml), sensor_hint);
}

SlamSettings read_settings_text(const std::string& yaml_text, const std::string& label,
                                std::optional<SensorType> sensor_hint) {
  return read_checked(SettingsFile(yaml_text, label), sensor_hint);
}

const char* sensor_type_name(SensorType type) {
  switch (type) {
    case SensorType::kMonocular:
      return "mono";
    case SensorType::kStereo:
      return "stereo";
    case SensorType::kMonocularInertial:
      return "mono_inertial";
    case SensorType::kStereoInertial:
      return "stereo_inertial";
    case SensorType::kRgbd:
      return "rgbd";
  }
  return "unknown";
}

std::optional<SensorType> parse_sensor_type(const std::string& name) {
  std::string n;
  for (const char c : name)
    n += (c == '-' || c == ' ') ? '_' : static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (n == "mono" || n == "monocular") return SensorType::kMonocular;
  if (n == "stereo") return SensorType::kStereo;
  if (n == "mono_inertial" || n == "monocular_inertial" || n == "imu_monocular") return SensorType::kMonocularInertial;
  if (n == "stereo_inertial" || n == "imu_stereo") return SensorType::kStereoInertial;
  if (n == "rgbd" || n == "rgb_d") return SensorType::kRgbd;
  return std::nullopt;
}

}  // namespace orbatlas
