#pragma once
// The one place that speaks ROS: reading and writing ROS 1 bags (format 2.0)
// with Debian's rosbag_storage and the sensor_msgs message definitions. Only
// standard types cross this header, because the ROS 1 message headers need
// C++17 (they use std::allocator::rebind, gone in C++20): rosbag_raw.cc is the
// only translation unit built with them. Everything else (EuRoC folders,
// calibration, checks) is in bag_dataset.h.
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace orbatlas::rosbag_raw {

// A sensor_msgs/Image as stored (its header.stamp in nanoseconds).
struct RawImage {
  std::string topic;
  std::int64_t t_ns = 0;
  std::uint32_t width = 0, height = 0, step = 0;
  std::string encoding;  // "mono8", "8UC1", "bgr8", ...
  std::vector<std::uint8_t> data;
};

// A sensor_msgs/Imu (header.stamp in nanoseconds; rad/s and m/s^2).
struct RawImu {
  std::int64_t t_ns = 0;
  double gyro[3] = {0, 0, 0};
  double accel[3] = {0, 0, 0};
};

struct TopicInfo {
  std::string topic, datatype;
  std::uint64_t messages = 0;
};

// Every topic of the bag with its message type and count. Throws
// std::runtime_error when the file is not a readable bag.
std::vector<TopicInfo> bag_topics(const std::string& path);

// Calls `on_image` for each sensor_msgs/Image on `image_topics` and `on_imu`
// for each sensor_msgs/Imu on `imu_topic` (none when empty), in the bag's time
// order. Throws std::runtime_error on a read error or a message of another type
// on those topics.
void read_bag(const std::string& path, const std::vector<std::string>& image_topics, const std::string& imu_topic,
              const std::function<void(RawImage&&)>& on_image, const std::function<void(const RawImu&)>& on_imu);

// Writes a bag (uncompressed chunks); messages are stamped (header and bag
// time) with their t_ns. Throws std::runtime_error on errors.
class BagWriter {
 public:
  explicit BagWriter(const std::string& path);
  ~BagWriter();
  BagWriter(const BagWriter&) = delete;
  BagWriter& operator=(const BagWriter&) = delete;
  void write_image(const RawImage& image);  // on image.topic
  void write_imu(const std::string& topic, const RawImu& imu);
  void close();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace orbatlas::rosbag_raw
