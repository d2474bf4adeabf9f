#pragma once
// The sensor.yaml files of an EuRoC ASL dataset (camera and IMU).
#include <filesystem>

#include "core/camera/camera_calibration.h"
#include "core/io/euroc_types.h"

namespace orbatlas {

// camera_model pinhole + distortion_model radial-tangential|radtan|equidistant.
CameraCalibration read_camera_sensor_yaml(const std::filesystem::path& yaml);
ImuCalibration read_imu_sensor_yaml(const std::filesystem::path& yaml);

void write_camera_sensor_yaml(const std::filesystem::path& yaml, const CameraCalibration& calibration,
                              const std::string& comment);
void write_imu_sensor_yaml(const std::filesystem::path& yaml, const ImuCalibration& calibration);

}  // namespace orbatlas
