#pragma once
// Writes an EuRoC ASL dataset incrementally: create the folders and sensor.yaml
// files, then add images, IMU rows and ground truth. Used by the simulator.
#include <filesystem>
#include <fstream>
#include <opencv2/core/mat.hpp>
#include <vector>

#include "core/io/euroc_types.h"

namespace orbatlas {

class EurocWriter {
 public:
  // Creates <root>/mav0/{cam0,cam1,imu0,state_groundtruth_estimate0} with their
  // sensor.yaml files. Refuses (Error) to write into a non-empty mav0/.
  EurocWriter(const std::filesystem::path& root, const std::vector<CameraCalibration>& cameras,
              const ImuCalibration& imu);

  // Path where the PNG of camera `cam` at time t must be written (the caller
  // encodes it, possibly on another thread).
  std::filesystem::path image_path(int cam, TimestampNs t) const;
  // Records a frame row in cam<cam>/data.csv (call in increasing time order).
  void add_frame_row(int cam, TimestampNs t);

  void write_imu(const std::vector<ImuSample>& samples);
  void write_ground_truth(const std::vector<GroundTruthState>& states);
  void close();  // flushes the csv files; throws on write errors

 private:
  std::filesystem::path mav0_;
  std::vector<std::ofstream> camera_csv_;
  std::ofstream imu_csv_;
  std::ofstream ground_truth_csv_;
  std::vector<TimestampNs> last_frame_t_;  // per camera; -1 before the first row
  TimestampNs last_imu_t_ = -1;
  TimestampNs last_ground_truth_t_ = -1;
};

}  // namespace orbatlas
