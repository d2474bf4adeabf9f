// ROS 1 bags (core/io/bag_dataset.h): a bag and the ASL folder of the same
// recording give the same frames, IMU and runs; bad bags are clear errors.
#include <gtest/gtest.h>

#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "core/common/data_paths.h"
#include "core/common/error.h"
#include "core/geometry/pose.h"
#include "core/io/bag_dataset.h"
#include "core/io/euroc_reader.h"
#include "core/pipeline/dataset_runner.h"
#include "tests/support/slam_test_clip.h"

namespace orbatlas {
namespace {

namespace fs = std::filesystem;

struct TempFolder {
  fs::path dir = fs::temp_directory_path() / ("orbatlas_test_bag_" + std::to_string(::getpid()));
  TempFolder() {
    fs::remove_all(dir);
    fs::create_directories(dir);
  }
  ~TempFolder() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
};

EurocDataset read_with_imu(const fs::path& dir) {
  EurocReadOptions o;
  o.require_cam1 = true;
  o.require_imu = true;
  return read_euroc_dataset(dir, o);
}

DatasetRunOptions run_options(const fs::path& dataset) {
  DatasetRunOptions o;
  o.settings = shipped_config_dir() / "euroc" / "stereo_inertial.yaml";
  o.dataset = dataset;
  o.show_progress = false;
  o.slam.synchronous_mapping = true;  // deterministic: equal inputs give equal runs
  return o;
}

TEST(Bag, ABagAndTheAslFolderOfOneRecordingGiveTheSameFramesImuAndRun) {
  const auto clip = test::simulated_clip("MH_01", 40.0, 4.0);
  test::ClipCleanup cleanup{clip};
  TempFolder tmp;
  const EurocDataset asl = read_with_imu(clip);
  const fs::path bag = tmp.dir / "clip.bag";
  write_bag(asl, BagTopics{}, bag);

  UnpackedBag unpacked(bag, BagTopics{}, bag_calibration_from_settings(), tmp.dir);
  EXPECT_EQ(unpacked.report().frames,
            (std::vector<std::size_t>{asl.cameras[0].frames.size(), asl.cameras[1].frames.size()}));
  EXPECT_EQ(unpacked.report().imu, asl.imu.size());
  const EurocDataset from_bag = read_with_imu(unpacked.dataset());

  // The same frames, pixel for pixel.
  ASSERT_EQ(from_bag.cameras.size(), 2u);
  for (std::size_t c = 0; c < 2; ++c) {
    ASSERT_EQ(from_bag.cameras[c].frames.size(), asl.cameras[c].frames.size()) << "cam" << c;
    for (std::size_t i = 0; i < asl.cameras[c].frames.size(); ++i) {
      ASSERT_EQ(from_bag.cameras[c].frames[i].t_ns, asl.cameras[c].frames[i].t_ns) << "cam" << c << " frame " << i;
      const cv::Mat a = cv::imread(asl.cameras[c].frames[i].path.string(), cv::IMREAD_GRAYSCALE);
      const cv::Mat b = cv::imread(from_bag.cameras[c].frames[i].path.string(), cv::IMREAD_GRAYSCALE);
      ASSERT_EQ(a.size(), b.size());
      ASSERT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0) << "cam" << c << " frame " << i;
    }
  }
  // The same IMU, to the last bit.
  ASSERT_EQ(from_bag.imu.size(), asl.imu.size());
  for (std::size_t i = 0; i < asl.imu.size(); ++i) {
    ASSERT_EQ(from_bag.imu[i].t_ns, asl.imu[i].t_ns) << i;
    ASSERT_EQ(from_bag.imu[i].gyro, asl.imu[i].gyro) << i;
    ASSERT_EQ(from_bag.imu[i].accel, asl.imu[i].accel) << i;
  }
  // The same stereo-inertial run, pose for pose.
  const DatasetRunReport a = run_dataset(run_options(clip));
  const DatasetRunReport b = run_dataset(run_options(unpacked.dataset()));
  ASSERT_GT(a.trajectory.size(), 70u);
  ASSERT_EQ(a.trajectory.size(), b.trajectory.size());
  // Two runs of one folder differ by about 1e-14 m (the solvers' threads add in
  // varying order): the bag's run is the folder's, far below tracking's errors.
  double worst_m = 0.0, worst_rad = 0.0;
  for (std::size_t i = 0; i < a.trajectory.size(); ++i) {
    ASSERT_EQ(a.trajectory[i].t_ns, b.trajectory[i].t_ns) << i;
    worst_m = std::max(worst_m, translation_distance(a.trajectory[i].pose, b.trajectory[i].pose));
    worst_rad = std::max(worst_rad, rotation_distance(a.trajectory[i].pose, b.trajectory[i].pose));
  }
  EXPECT_LT(worst_m, 1e-9);
  EXPECT_LT(worst_rad, 1e-9);
  EXPECT_EQ(a.stats.keyframes, b.stats.keyframes);

  // A single camera from the same bag, without its IMU.
  BagTopics left_only;
  left_only.cam1.clear();
  left_only.imu.clear();
  UnpackedBag left(bag, left_only, bag_calibration_from_settings(), tmp.dir);
  const EurocDataset mono = read_euroc_dataset(left.dataset());
  EXPECT_EQ(mono.cameras.size(), 1u);
  EXPECT_EQ(mono.cameras[0].frames.size(), asl.cameras[0].frames.size());
  EXPECT_TRUE(mono.imu.empty());
  EXPECT_EQ(left.report().other_topics.size(), 2u);  // /cam1/image_raw and /imu0, named
  const fs::path unpacked_dir = left.dataset();
  { UnpackedBag gone(bag, left_only, bag_calibration_from_settings(), tmp.dir); }
  EXPECT_TRUE(fs::exists(unpacked_dir)) << "the first folder is still in use";
}

TEST(Bag, BadBagsAreClearErrors) {
  TempFolder tmp;
  const BagCalibration calibration = bag_calibration_from_settings();
  const auto message_of = [&](const fs::path& bag, const BagTopics& topics) {
    try {
      unpack_bag(bag, topics, calibration, tmp.dir / "out");
    } catch (const DataError& e) {
      return std::string(e.what());
    }
    ADD_FAILURE() << "no DataError for " << bag;
    return std::string();
  };
  // Not a bag at all.
  const fs::path text = tmp.dir / "notes.bag";
  std::ofstream(text) << "not a bag\n";
  EXPECT_NE(message_of(text, BagTopics{}).find("not a readable ROS bag"), std::string::npos);
  EXPECT_NE(message_of(tmp.dir / "missing.bag", BagTopics{}).find("missing.bag"), std::string::npos);

  // A bag with one camera: asking for the second names what the bag has.
  const auto clip = test::simulated_clip("MH_01", 40.0, 0.5);
  test::ClipCleanup cleanup{clip};
  EurocDataset asl = read_with_imu(clip);
  asl.cameras.resize(1);
  const fs::path bag = tmp.dir / "left.bag";
  write_bag(asl, BagTopics{}, bag);
  const std::string missing = message_of(bag, BagTopics{});
  EXPECT_NE(missing.find("has no topic /cam1/image_raw"), std::string::npos) << missing;
  EXPECT_NE(missing.find("/imu0 (sensor_msgs/Imu"), std::string::npos) << missing;
  // The IMU's topic given as a camera's.
  BagTopics wrong;
  wrong.cam0 = "/imu0";
  wrong.cam1.clear();
  const std::string type = message_of(bag, wrong);
  EXPECT_NE(type.find("is not sensor_msgs/Image"), std::string::npos) << type;
  EXPECT_FALSE(fs::exists(tmp.dir / "out" / "mav0")) << "a refused bag unpacks nothing";
}

}  // namespace
}  // namespace orbatlas
