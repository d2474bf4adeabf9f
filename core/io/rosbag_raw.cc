// Built as C++17 (see rosbag_raw.h): ROS 1's generated message headers.
#include "core/io/rosbag_raw.h"

#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>

#include <set>
#include <stdexcept>

namespace orbatlas::rosbag_raw {
namespace {

std::runtime_error bag_error(const std::string& path, const std::string& what) {
  return std::runtime_error(path + ": " + what);
}

std::int64_t nanoseconds(const ros::Time& t) { return static_cast<std::int64_t>(t.toNSec()); }

ros::Time ros_time(std::int64_t t_ns) {
  if (t_ns < 0) throw std::runtime_error("a bag cannot hold a negative timestamp (" + std::to_string(t_ns) + " ns)");
  ros::Time t;
  t.fromNSec(static_cast<std::uint64_t>(t_ns));
  return t;
}

}  // namespace

std::vector<TopicInfo> bag_topics(const std::string& path) {
  try {
    rosbag::Bag bag(path, rosbag::bagmode::Read);
    rosbag::View view(bag);
    std::vector<TopicInfo> out;
    for (const rosbag::ConnectionInfo* c : view.getConnections()) {
      bool seen = false;
      for (TopicInfo& t : out)
        if (t.topic == c->topic) seen = true;
      if (!seen) out.push_back({c->topic, c->datatype, 0});
    }
    for (TopicInfo& t : out) t.messages = rosbag::View(bag, rosbag::TopicQuery(t.topic)).size();
    return out;
  } catch (const rosbag::BagException& e) {
    throw bag_error(path, std::string("not a readable ROS bag (") + e.what() + ")");
  }
}

void read_bag(const std::string& path, const std::vector<std::string>& image_topics, const std::string& imu_topic,
              const std::function<void(RawImage&&)>& on_image, const std::function<void(const RawImu&)>& on_imu) {
  std::vector<std::string> topics = image_topics;
  if (!imu_topic.empty()) topics.push_back(imu_topic);
  const std::set<std::string> images(image_topics.begin(), image_topics.end());
  try {
    rosbag::Bag bag(path, rosbag::bagmode::Read);
    rosbag::View view(bag, rosbag::TopicQuery(topics));
    for (const rosbag::MessageInstance& m : view) {
      if (images.count(m.getTopic())) {
        const auto msg = m.instantiate<sensor_msgs::Image>();
        if (!msg)
          throw bag_error(path, "topic " + m.getTopic() + " holds " + m.getDataType() + ", not sensor_msgs/Image");
        RawImage image;
        image.topic = m.getTopic();
        image.t_ns = nanoseconds(msg->header.stamp);
        image.width = msg->width;
        image.height = msg->height;
        image.step = msg->step;
        image.encoding = msg->encoding;
        image.data = std::move(msg->data);
        on_image(std::move(image));
      } else {
        const auto msg = m.instantiate<sensor_msgs::Imu>();
        if (!msg)
          throw bag_error(path, "topic " + m.getTopic() + " holds " + m.getDataType() + ", not sensor_msgs/Imu");
        RawImu imu;
        imu.t_ns = nanoseconds(msg->header.stamp);
        imu.gyro[0] = msg->angular_velocity.x;
        imu.gyro[1] = msg->angular_velocity.y;
        imu.gyro[2] = msg->angular_velocity.z;
        imu.accel[0] = msg->linear_acceleration.x;
        imu.accel[1] = msg->linear_acceleration.y;
        imu.accel[2] = msg->linear_acceleration.z;
        on_imu(imu);
      }
    }
  } catch (const rosbag::BagException& e) {
    throw bag_error(path, std::string("cannot read the bag (") + e.what() + ")");
  } catch (const ros::Exception& e) {
    throw bag_error(path, std::string("cannot decode a message (") + e.what() + ")");
  }
}

struct BagWriter::Impl {
  std::string path;
  rosbag::Bag bag;
  std::uint32_t image_seq = 0, imu_seq = 0;
};

BagWriter::BagWriter(const std::string& path) : impl_(std::make_unique<Impl>()) {
  impl_->path = path;
  try {
    impl_->bag.open(path, rosbag::bagmode::Write);
  } catch (const rosbag::BagException& e) {
    throw bag_error(path, std::string("cannot create the bag (") + e.what() + ")");
  }
}

BagWriter::~BagWriter() {
  try {
    impl_->bag.close();
  } catch (...) {
  }
}

void BagWriter::write_image(const RawImage& image) {
  sensor_msgs::Image msg;
  msg.header.seq = impl_->image_seq++;
  msg.header.stamp = ros_time(image.t_ns);
  msg.header.frame_id = image.topic;
  msg.width = image.width;
  msg.height = image.height;
  msg.step = image.step;
  msg.encoding = image.encoding;
  msg.is_bigendian = 0;
  msg.data = image.data;
  try {
    impl_->bag.write(image.topic, msg.header.stamp, msg);
  } catch (const rosbag::BagException& e) {
    throw bag_error(impl_->path, std::string("cannot write (") + e.what() + ")");
  }
}

void BagWriter::write_imu(const std::string& topic, const RawImu& imu) {
  sensor_msgs::Imu msg;
  msg.header.seq = impl_->imu_seq++;
  msg.header.stamp = ros_time(imu.t_ns);
  msg.header.frame_id = topic;
  msg.angular_velocity.x = imu.gyro[0];
  msg.angular_velocity.y = imu.gyro[1];
  msg.angular_velocity.z = imu.gyro[2];
  msg.linear_acceleration.x = imu.accel[0];
  msg.linear_acceleration.y = imu.accel[1];
  msg.linear_acceleration.z = imu.accel[2];
  msg.orientation_covariance[0] = -1.0;  // no orientation estimate (sensor_msgs/Imu's convention)
  try {
    impl_->bag.write(topic, msg.header.stamp, msg);
  } catch (const rosbag::BagException& e) {
    throw bag_error(impl_->path, std::string("cannot write (") + e.what() + ")");
  }
}

void BagWriter::close() {
  try {
    impl_->bag.close();
  } catch (const rosbag::BagException& e) {
    throw bag_error(impl_->path, std::string("cannot close the bag (") + e.what() + ")");
  }
}

}  // namespace orbatlas::rosbag_raw
