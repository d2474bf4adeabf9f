#include "core/io/bag_dataset.h"

#include <cstdlib>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "core/common/data_paths.h"
#include "core/common/error.h"
#include "core/common/log.h"
#include "core/common/progress.h"
#include "core/io/euroc_writer.h"
#include "core/io/rosbag_raw.h"
#include "core/io/settings.h"

namespace orbatlas {
namespace fs = std::filesystem;

namespace {

// The grey image of a sensor_msgs/Image (its pixels copied).
cv::Mat grey_image(const rosbag_raw::RawImage& m, const fs::path& bag) {
  int channels = 0, code = -1;
  if (m.encoding == "mono8" || m.encoding == "8UC1") {
    channels = 1;
  } else if (m.encoding == "bgr8" || m.encoding == "8UC3") {
    channels = 3;
    code = cv::COLOR_BGR2GRAY;
  } else if (m.encoding == "rgb8") {
    channels = 3;
    code = cv::COLOR_RGB2GRAY;
  } else if (m.encoding == "bgra8" || m.encoding == "8UC4") {
    channels = 4;
    code = cv::COLOR_BGRA2GRAY;
  } else if (m.encoding == "rgba8") {
    channels = 4;
    code = cv::COLOR_RGBA2GRAY;
  }
  ORBATLAS_DATA_CHECK(channels > 0, bag.string()
                                        << ": " << m.topic << " at " << m.t_ns << " ns: image encoding '" << m.encoding
                                        << "' (mono8, 8UC1, bgr8, rgb8, bgra8 or rgba8 expected)");
  ORBATLAS_DATA_CHECK(m.width > 0 && m.height > 0 && m.width <= 16384 && m.height <= 16384,
                      bag.string() << ": " << m.topic << " at " << m.t_ns << " ns: image of " << m.width << "x"
                                   << m.height << " pixels");
  const std::size_t row = static_cast<std::size_t>(m.width) * static_cast<std::size_t>(channels);
  ORBATLAS_DATA_CHECK(m.step >= row && m.data.size() >= static_cast<std::size_t>(m.step) * m.height,
                      bag.string() << ": " << m.topic << " at " << m.t_ns << " ns: " << m.width << "x" << m.height
                                   << " " << m.encoding << " with step " << m.step << " needs "
                                   << static_cast<std::size_t>(m.step) * m.height << " bytes, the message holds "
                                   << m.data.size());
  const cv::Mat view(static_cast<int>(m.height), static_cast<int>(m.width), CV_8UC(channels),
                     const_cast<std::uint8_t*>(m.data.data()), m.step);
  cv::Mat grey;
  if (code < 0)
    grey = view.clone();
  else
    cv::cvtColor(view, grey, code);
  return grey;
}

std::string describe(const rosbag_raw::TopicInfo& t) {
  return t.topic + " (" + t.datatype + ", " + std::to_string(t.messages) + " messages)";
}

}  // namespace

BagCalibration bag_calibration_from_settings(const fs::path& settings_yaml) {
  const fs::path path = settings_yaml.empty() ? shipped_config_dir() / "euroc" / "stereo_inertial.yaml" : settings_yaml;
  const SlamSettings settings = read_settings(path);
  BagCalibration out;
  out.cameras.push_back(settings.camera0);
  if (settings.camera1) out.cameras.push_back(*settings.camera1);
  out.imu = settings.imu.value_or(ImuCalibration{});
  return out;
}

BagUnpackReport unpack_bag(const fs::path& bag, const BagTopics& topics, const BagCalibration& calibration,
                           const fs::path& out, bool show_progress) {
  std::vector<rosbag_raw::TopicInfo> in_bag;
  try {
    in_bag = rosbag_raw::bag_topics(bag.string());
  } catch (const std::runtime_error& e) {
    throw DataError(e.what());
  }
  const auto find = [&](const std::string& topic) -> const rosbag_raw::TopicInfo* {
    for (const auto& t : in_bag)
      if (t.topic == topic) return &t;
    return nullptr;
  };
  std::string listing;
  for (const auto& t : in_bag) listing += (listing.empty() ? "" : ", ") + describe(t);
  std::vector<std::string> cameras = {topics.cam0};
  if (!topics.cam1.empty()) cameras.push_back(topics.cam1);
  ORBATLAS_CHECK(!topics.cam0.empty(), "a bag needs a camera topic (cam0)");
  ORBATLAS_CHECK(calibration.cameras.size() >= cameras.size(), "the calibration has " << calibration.cameras.size()
                                                                                      << " camera(s), the bag's topics "
                                                                                      << cameras.size());
  std::size_t total = 0;
  for (const std::string& topic : cameras) {
    const rosbag_raw::TopicInfo* t = find(topic);
    ORBATLAS_DATA_CHECK(t, bag.string() << " has no topic " << topic << " (it has " << listing
                                        << "); name the cameras' topics with --cam0-topic / --cam1-topic");
    ORBATLAS_DATA_CHECK(t->datatype == "sensor_msgs/Image", bag.string()
                                                                << ": " << describe(*t) << " is not sensor_msgs/Image");
    total += t->messages;
  }
  std::string imu_topic = topics.imu;
  if (!imu_topic.empty()) {
    const rosbag_raw::TopicInfo* t = find(imu_topic);
    if (!t) {
      log_info(bag.string() + " has no IMU topic " + imu_topic + ": unpacked without IMU");
      imu_topic.clear();
    } else {
      ORBATLAS_DATA_CHECK(t->datatype == "sensor_msgs/Imu", bag.string()
                                                                << ": " << describe(*t) << " is not sensor_msgs/Imu");
    }
  }

  BagUnpackReport report;
  report.frames.assign(cameras.size(), 0);
  for (const auto& t : in_bag) {
    bool used = t.topic == imu_topic;
    for (const std::string& c : cameras) used = used || t.topic == c;
    if (!used) report.other_topics.push_back(describe(t));
  }
  const std::vector<CameraCalibration> cams(calibration.cameras.begin(),
                                            calibration.cameras.begin() + static_cast<std::ptrdiff_t>(cameras.size()));
  EurocWriter writer(out, cams, calibration.imu);
  std::vector<ImuSample> imu;
  std::vector<TimestampNs> last(cameras.size(), -1);
  Progress progress("unpacking " + bag.filename().string(), static_cast<std::int64_t>(total), show_progress);
  const std::vector<int> png = {cv::IMWRITE_PNG_COMPRESSION, 1};  // lossless either way; level 1 is fast
  try {
    rosbag_raw::read_bag(
        bag.string(), cameras, imu_topic,
        [&](rosbag_raw::RawImage&& m) {
          const int cam = m.topic == cameras[0] ? 0 : 1;
          const auto c = static_cast<std::size_t>(cam);
          ORBATLAS_DATA_CHECK(m.t_ns > last[c], bag.string() << ": " << m.topic << ": an image at " << m.t_ns
                                                             << " ns after one at " << last[c]
                                                             << " ns (header stamps must increase)");
          last[c] = m.t_ns;
          const cv::Mat grey = grey_image(m, bag);
          const fs::path file = writer.image_path(cam, m.t_ns);
          ORBATLAS_CHECK(cv::imwrite(file.string(), grey, png), "cannot write " << file.string());
          writer.add_frame_row(cam, m.t_ns);
          ++report.frames[c];
          progress.advance();
        },
        [&](const rosbag_raw::RawImu& m) {
          ORBATLAS_DATA_CHECK(imu.empty() || m.t_ns > imu.back().t_ns,
                              bag.string() << ": " << imu_topic << ": a sample at " << m.t_ns << " ns after one at "
                                           << imu.back().t_ns << " ns (header stamps must increase)");
          ImuSample s;
          s.t_ns = m.t_ns;
          s.gyro = Eigen::Vector3d(m.gyro[0], m.gyro[1], m.gyro[2]);
          s.accel = Eigen::Vector3d(m.accel[0], m.accel[1], m.accel[2]);
          // A sample that is not finite is kept as read: the session drops it and says so
          // (core/imu/imu_input_check.h).
          imu.push_back(s);
        });
  } catch (const std::runtime_error& e) {
    if (dynamic_cast<const Error*>(&e)) throw;
    throw DataError(e.what());
  }
  writer.write_imu(imu);
  writer.close();
  progress.finish();
  report.imu = imu.size();
  for (std::size_t c = 0; c < cameras.size(); ++c)
    ORBATLAS_DATA_CHECK(report.frames[c] > 0, bag.string() << ": no image on " << cameras[c]);
  return report;
}

void write_bag(const EurocDataset& dataset, const BagTopics& topics, const fs::path& bag) {
  ORBATLAS_CHECK(!dataset.cameras.empty(), "write_bag: the recording has no camera");
  rosbag_raw::BagWriter writer(bag.string());
  try {
    const auto write_camera = [&](const CameraStream& stream, const std::string& topic) {
      for (const ImageFrame& f : stream.frames) {
        const cv::Mat grey = cv::imread(f.path.string(), cv::IMREAD_GRAYSCALE);
        ORBATLAS_DATA_CHECK(!grey.empty(), "cannot read the image " << f.path.string());
        rosbag_raw::RawImage m;
        m.topic = topic;
        m.t_ns = f.t_ns;
        m.width = static_cast<std::uint32_t>(grey.cols);
        m.height = static_cast<std::uint32_t>(grey.rows);
        m.step = m.width;
        m.encoding = "mono8";
        m.data.assign(grey.datastart, grey.dataend);  // a decoded image is continuous: rows of `width` bytes
        writer.write_image(m);
      }
    };
    write_camera(dataset.cameras[0], topics.cam0);
    if (dataset.cameras.size() > 1 && !topics.cam1.empty()) write_camera(dataset.cameras[1], topics.cam1);
    if (!topics.imu.empty())
      for (const ImuSample& s : dataset.imu) {
        rosbag_raw::RawImu m;
        m.t_ns = s.t_ns;
        for (int i = 0; i < 3; ++i) {
          m.gyro[i] = s.gyro[i];
          m.accel[i] = s.accel[i];
        }
        writer.write_imu(topics.imu, m);
      }
    writer.close();
  } catch (const std::runtime_error& e) {
    if (dynamic_cast<const Error*>(&e)) throw;
    throw Error(e.what());
  }
}

UnpackedBag::UnpackedBag(const fs::path& bag, const BagTopics& topics, const BagCalibration& calibration,
                         const fs::path& parent, bool show_progress) {
  const fs::path base = parent.empty() ? fs::temp_directory_path() : parent;
  std::string pattern = (base / "orbatlas-bag-XXXXXX").string();
  ORBATLAS_CHECK(::mkdtemp(pattern.data()) != nullptr,
                 "cannot create a folder under " << base.string() << " to unpack " << bag.string());
  dir_ = pattern;
  try {
    report_ = unpack_bag(bag, topics, calibration, dir_, show_progress);
  } catch (...) {
    std::error_code ec;
    fs::remove_all(dir_, ec);
    throw;
  }
}

UnpackedBag::~UnpackedBag() {
  std::error_code ec;
  fs::remove_all(dir_, ec);
}

}  // namespace orbatlas
