#pragma once
// In-memory form of an EuRoC ASL dataset (mav0/cam0, cam1, imu0,
// state_groundtruth_estimate0 and their sensor.yaml files).
#include <Eigen/Core>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "core/camera/camera_calibration.h"
#include "core/common/timestamp.h"
#include "core/geometry/pose.h"

namespace orbatlas {

struct ImuSample {
  TimestampNs t_ns = 0;
  Eigen::Vector3d gyro = Eigen::Vector3d::Zero();   // rad/s, IMU frame
  Eigen::Vector3d accel = Eigen::Vector3d::Zero();  // m/s^2 specific force, IMU frame
};

struct ImuCalibration {
  Pose3 T_b_i;  // IMU in the body frame (identity for EuRoC)
  double rate_hz = 200.0;
  double gyro_noise_density = 1.6968e-04;   // rad/s/sqrt(Hz)
  double gyro_random_walk = 1.9393e-05;     // rad/s^2/sqrt(Hz)
  double accel_noise_density = 2.0000e-03;  // m/s^2/sqrt(Hz)
  double accel_random_walk = 3.0000e-03;    // m/s^3/sqrt(Hz)
  // The sensor's range (IMU.GyroRange, IMU.AccRange; 0: not given): readings
  // at it are saturated (core/imu/imu_input_check.h).
  double gyro_range = 0.0;   // rad/s
  double accel_range = 0.0;  // m/s^2
};

// One row of state_groundtruth_estimate0/data.csv.
struct GroundTruthState {
  TimestampNs t_ns = 0;
  Pose3 T_w_b;
  Eigen::Vector3d v_w = Eigen::Vector3d::Zero();
  Eigen::Vector3d gyro_bias = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel_bias = Eigen::Vector3d::Zero();
};

struct ImageFrame {
  TimestampNs t_ns = 0;
  std::filesystem::path path;  // absolute or relative to the working directory
};

struct CameraStream {
  CameraCalibration calibration;
  std::vector<ImageFrame> frames;  // strictly increasing timestamps, files exist
};

struct EurocDataset {
  std::filesystem::path root;         // the folder holding mav0/
  std::vector<CameraStream> cameras;  // cam0 [, cam1]
  std::optional<ImuCalibration> imu_calibration;
  std::vector<ImuSample> imu;                  // empty when there is no imu0
  std::vector<GroundTruthState> ground_truth;  // empty when absent
  std::vector<std::string> warnings;           // every row skipped, and why
};

}  // namespace orbatlas
