#pragma once
// `--bag FILE` and its topic options, shared by run, localize, stream and
// upload: each bag is unpacked into a temporary EuRoC ASL folder (its
// calibration from --bag-calibration, default EuRoC's) that the command then
// reads as it reads --dataset; the folders go when the command ends.
#include <CLI/CLI.hpp>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "core/io/bag_dataset.h"

namespace orbatlas::cli {

struct BagArgs {
  std::vector<std::string> bags;
  BagTopics topics;
  std::string calibration;  // settings file; empty: config/euroc/stereo_inertial.yaml
  std::string unpack_dir;   // empty: $TMPDIR
};

// Adds --bag (repeatable when `several`), --cam0-topic, --cam1-topic,
// --imu-topic, --bag-calibration and --unpack-dir; returns the --bag option.
CLI::Option* add_bag_options(CLI::App* cmd, BagArgs& args, bool several);

class UnpackedBags {
 public:
  // Unpacks every bag in turn (progress on stderr when `show_progress`).
  UnpackedBags(const BagArgs& args, bool show_progress);
  std::vector<std::filesystem::path> datasets() const;

 private:
  std::vector<std::unique_ptr<UnpackedBag>> bags_;
};

// The one recording of a command that takes --dataset or --bag: the folder to
// read (`dataset`, or the unpacked bag kept alive in `holder`).
std::filesystem::path dataset_or_bag(const std::string& dataset, const BagArgs& bag,
                                     std::unique_ptr<UnpackedBags>& holder, bool show_progress);

}  // namespace orbatlas::cli
