#pragma once
// What `orbatlas run` reads before anything starts (core/pipeline/dataset_runner):
// the settings, the recording and the frames of its time window, for each kind
// of recording (an EuRoC ASL folder, a KITTI odometry sequence, a TUM RGB-D
// folder) and sensor (a stereo rig, its left camera alone, RGB-D, with an IMU).
#include <vector>

#include "core/io/euroc_reader.h"
#include "core/io/settings.h"
#include "core/pipeline/dataset_runner.h"

namespace orbatlas {

struct RunInputs {
  SlamSettings settings;
  EurocDataset dataset;  // its IMU and ground truth (of the body)
  std::vector<DatasetFrame> frames;
};

// Throws Error for settings that do not fit the recording, a recording that
// cannot be read (DataError naming the file), or an empty time window.
RunInputs read_run_inputs(const DatasetRunOptions& options);

}  // namespace orbatlas
