#pragma once
// SLAM settings from an ORB-SLAM3 v1.0-style YAML file (cv::FileStorage), so that
// users can bring their existing calibration. See docs/settings.md for every key.
#include <filesystem>
#include <map>
#include <optional>
#include <string>

#include "core/camera/camera_calibration.h"
#include "core/io/euroc_types.h"

namespace orbatlas {

enum class SensorType { kMonocular, kStereo, kMonocularInertial, kStereoInertial, kRgbd };

// A depth camera registered to camera0 (ORB-SLAM3's RGB-D keys): each image
// pixel's depth is its 16-bit value / depth_map_factor metres (0: none), and a
// keypoint with depth gets a virtual right image coordinate u - bf / depth
// with bf = baseline_m * fx, so the stereo machinery serves.
struct RgbdCalibration {
  double depth_map_factor = 5000.0;  // RGBD.DepthMapFactor (TUM: 5000 per metre)
  double baseline_m = 0.08;          // Stereo.b: the virtual baseline (ORB-SLAM3: the projector's)
};

struct OrbSettings {
  int n_features = 1200;
  double scale_factor = 1.2;
  int n_levels = 8;
  int ini_th_fast = 20;
  int min_th_fast = 7;
};

// Limits SlamSettings::check() enforces (ORB-SLAM3 uses 1000-2000 features and
// cameras of at most a few thousand pixels a side).
inline constexpr int kMaxOrbFeatures = 20000;
inline constexpr int kMaxImageSide = 8192;

struct SlamSettings {
  SensorType sensor = SensorType::kStereo;
  CameraCalibration camera0;                 // Camera1.* in the file; T_b_c from IMU.T_b_c1
  std::optional<CameraCalibration> camera1;  // Camera2.*; T_b_c = T_b_c0 * Stereo.T_c1_c2
  Pose3 T_c0_c1;                             // Stereo.T_c1_c2 (identity for mono)
  double fps = 20.0;
  bool rgb = true;
  double stereo_th_depth = 60.0;  // close/far threshold in baselines
  std::optional<ImuCalibration> imu;
  std::optional<RgbdCalibration> rgbd;  // for the rgbd sensor
  OrbSettings orb;
  // The optional `Orbatlas.*` keys (the engine's own tuning, docs/settings.md),
  // without the prefix: "Tracker.MinInliers" -> 40. Numbers only; which keys exist
  // and their ranges are checked where they apply (core/slam/slam_tuning.h).
  std::map<std::string, double> orbatlas;

  bool is_stereo() const { return sensor == SensorType::kStereo || sensor == SensorType::kStereoInertial; }
  bool is_inertial() const { return sensor == SensorType::kMonocularInertial || sensor == SensorType::kStereoInertial; }
  bool is_rgbd() const { return sensor == SensorType::kRgbd; }
  // Throws Error when something needed for the sensor type is missing or invalid.
  void check() const;
};

// The sensor type is not in ORB-SLAM3 files (it is chosen by the example
// program): it comes from the key "Sensor.type" ("mono", "stereo",
// "mono_inertial", "stereo_inertial", "rgbd") when present, else from
// `sensor_hint`, else rgbd when RGBD.DepthMapFactor is present, stereo when
// Camera2 / Stereo.* keys are present and mono otherwise, inertial when IMU.*
// keys are present.
SlamSettings read_settings(const std::filesystem::path& yaml, std::optional<SensorType> sensor_hint = {});
// The same from YAML text in memory (a request's settings); errors name `label`.
SlamSettings read_settings_text(const std::string& yaml_text, const std::string& label,
                                std::optional<SensorType> sensor_hint = {});

const char* sensor_type_name(SensorType type);
std::optional<SensorType> parse_sensor_type(const std::string& name);

}  // namespace orbatlas
