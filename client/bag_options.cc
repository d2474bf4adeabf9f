#include "client/bag_options.h"

#include <cstdio>

#include "core/common/error.h"

namespace orbatlas::cli {

CLI::Option* add_bag_options(CLI::App* cmd, BagArgs& args, bool several) {
  CLI::Option* bag =
      cmd->add_option("--bag", args.bags,
                      std::string("A ROS 1 bag (sensor_msgs/Image, sensor_msgs/Imu) instead of a folder") +
                          (several ? "; repeat it for several recordings" : ""))
          ->check(CLI::ExistingFile);
  if (!several) bag->expected(1);
  cmd->add_option("--cam0-topic", args.topics.cam0, "With --bag: the left (or only) camera's topic")
      ->capture_default_str();
  cmd->add_option("--cam1-topic", args.topics.cam1, "With --bag: the right camera's topic ('' for a single camera)")
      ->capture_default_str();
  cmd->add_option("--imu-topic", args.topics.imu, "With --bag: the IMU's topic ('' for none)")->capture_default_str();
  cmd->add_option("--bag-calibration", args.calibration,
                  "With --bag: settings file whose Camera1/Camera2/IMU calibrate the bag (default: EuRoC's, "
                  "config/euroc/stereo_inertial.yaml)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--unpack-dir", args.unpack_dir,
                  "With --bag: where to unpack it (default: the temporary folder; about the bag's size)")
      ->check(CLI::ExistingDirectory);
  return bag;
}

UnpackedBags::UnpackedBags(const BagArgs& args, bool show_progress) {
  if (args.bags.empty()) return;
  const BagCalibration calibration = bag_calibration_from_settings(args.calibration);
  for (const std::string& bag : args.bags) {
    bags_.push_back(std::make_unique<UnpackedBag>(bag, args.topics, calibration, args.unpack_dir, show_progress));
    const BagUnpackReport& r = bags_.back()->report();
    std::fprintf(stderr, "[bag] %s: %zu frames", bag.c_str(), r.frames.front());
    if (r.frames.size() > 1) std::fprintf(stderr, " + %zu", r.frames[1]);
    std::fprintf(stderr, ", %zu IMU samples", r.imu);
    for (const std::string& other : r.other_topics) std::fprintf(stderr, "; not read: %s", other.c_str());
    std::fprintf(stderr, "\n");
  }
}

std::vector<std::filesystem::path> UnpackedBags::datasets() const {
  std::vector<std::filesystem::path> out;
  for (const auto& b : bags_) out.push_back(b->dataset());
  return out;
}

std::filesystem::path dataset_or_bag(const std::string& dataset, const BagArgs& bag,
                                     std::unique_ptr<UnpackedBags>& holder, bool show_progress) {
  if (bag.bags.empty() == dataset.empty())
    throw Error("give either --dataset or --bag (" + std::string(dataset.empty() ? "neither was" : "both were") +
                " given)");
  if (!dataset.empty()) return dataset;
  holder = std::make_unique<UnpackedBags>(bag, show_progress);
  return holder->datasets().front();
}

}  // namespace orbatlas::cli
