#pragma once
// ROS 1 bags as recordings (`--bag` on run, localize, stream and upload;
// `orbatlas sim --bag`). EuRoC is also distributed as bags with /cam0/image_raw,
// /cam1/image_raw (sensor_msgs/Image, mono8) and /imu0 (sensor_msgs/Imu);
// most robot logs are bags. A bag carries no calibration: it comes from an
// ORB-SLAM3-style settings file (Camera1/Camera2 and IMU.*), by default the
// shipped config/euroc/stereo_inertial.yaml (EuRoC's own calibration).
//
// A bag is read by unpacking it into an EuRoC ASL folder (lossless PNG images,
// the IMU csv, sensor.yaml files from the calibration), which every command
// already reads: the same frames, IMU and runs as the ASL folder of the same
// recording (tests/io/test_bag.cc). The folder takes about the bag's size on disk.
#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "core/io/euroc_types.h"

namespace orbatlas {

struct BagTopics {
  std::string cam0 = "/cam0/image_raw";
  std::string cam1 = "/cam1/image_raw";  // empty: a single camera
  std::string imu = "/imu0";             // empty: no IMU
};

struct BagCalibration {
  std::vector<CameraCalibration> cameras;  // cam0 [, cam1]
  ImuCalibration imu;
};

// Camera1 (and Camera2) and the IMU of a settings file; empty path: the
// shipped config/euroc/stereo_inertial.yaml.
BagCalibration bag_calibration_from_settings(const std::filesystem::path& settings_yaml = {});

struct BagUnpackReport {
  std::vector<std::size_t> frames;  // per camera
  std::size_t imu = 0;
  std::vector<std::string> other_topics;  // in the bag, not read ("topic (type, n messages)")
};

// Unpacks the bag's camera topics and IMU into an ASL folder at `out` (created;
// refused when its mav0/ is not empty). Images must be mono8 / 8UC1 (bgr8,
// rgb8, bgra8 and rgba8 are converted to grey). DataError for an unreadable
// bag, a topic that is missing or of another type, an image whose size or
// step does not match its data, timestamps that do not increase.
BagUnpackReport unpack_bag(const std::filesystem::path& bag, const BagTopics& topics, const BagCalibration& calibration,
                           const std::filesystem::path& out, bool show_progress = false);

// Writes an ASL recording as a bag: its images (mono8) and IMU on `topics`
// (cam1 and the IMU only when the recording has them and the topic is set).
void write_bag(const EurocDataset& dataset, const BagTopics& topics, const std::filesystem::path& bag);

// A bag unpacked into a fresh temporary folder (under $TMPDIR, or `parent`)
// for the life of the object, then removed.
class UnpackedBag {
 public:
  UnpackedBag(const std::filesystem::path& bag, const BagTopics& topics, const BagCalibration& calibration,
              const std::filesystem::path& parent = {}, bool show_progress = false);
  ~UnpackedBag();
  UnpackedBag(const UnpackedBag&) = delete;
  UnpackedBag& operator=(const UnpackedBag&) = delete;
  const std::filesystem::path& dataset() const { return dir_; }
  const BagUnpackReport& report() const { return report_; }

 private:
  std::filesystem::path dir_;
  BagUnpackReport report_;
};

}  // namespace orbatlas
