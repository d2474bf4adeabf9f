#pragma once
// A short simulated Machine Hall clip for the SLAM tests, rendered once per test
// process into its own temporary folder (ctest runs tests in parallel processes).
#include <unistd.h>

#include <filesystem>
#include <optional>
#include <string>

#include "core/io/euroc_reader.h"
#include "core/sim/sequence_simulator.h"

namespace orbatlas::test {

// With `depth`, also the depth camera's TUM RGB-D layout (sim --depth). With
// `imu_errors`, the synthetic IMU carries them (else the look's: the clean
// look's IMU is ideal); `imu_name` tells such clips apart.
inline std::filesystem::path simulated_clip(const std::string& sequence, double start_s, double duration_s,
                                            bool depth = false,
                                            const std::optional<sim::ImuErrorModel>& imu_errors = std::nullopt,
                                            const std::string& imu_name = "") {
  const auto dir =
      std::filesystem::temp_directory_path() /
      ("orbatlas_test_slam_" + std::to_string(::getpid()) + "_" + sequence + "_" +
       std::to_string(static_cast<int>(start_s * 10)) + "_" + std::to_string(static_cast<int>(duration_s * 10)) +
       (depth ? "_depth" : "") + (imu_errors ? "_imu_" + imu_name : ""));
  if (std::filesystem::exists(dir / "mav0" / "cam1" / "data.csv") &&
      (!depth || std::filesystem::exists(dir / "depth.txt")))
    return dir;
  std::filesystem::remove_all(dir);
  sim::SimulationOptions o;
  o.sequence = sequence;
  o.out_dir = dir;
  o.start_s = start_s;
  o.duration_s = duration_s;
  o.show_progress = false;
  if (depth) o.depth = sim::DepthSensorOptions{};
  o.imu_errors = imu_errors;
  sim::simulate_sequence(o);
  return dir;
}

// The stereo frames of a clip (or any ASL folder with cam0 and cam1).
inline EurocDataset stereo_dataset(const std::filesystem::path& dir) {
  EurocReadOptions ro;
  ro.require_cam1 = true;
  return read_euroc_dataset(dir, ro);
}
inline std::vector<DatasetFrame> stereo_frames(const std::filesystem::path& dir) {
  return pair_stereo_frames(stereo_dataset(dir));
}

// Removes a clip folder when the test process ends.
struct ClipCleanup {
  std::filesystem::path dir;
  ~ClipCleanup() {
    std::error_code ec;
    std::filesystem::remove_all(dir, ec);
  }
};

}  // namespace orbatlas::test
