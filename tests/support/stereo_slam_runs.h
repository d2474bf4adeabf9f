#pragma once
// What the stereo SLAM tests share: the shipped EuRoC stereo settings, a run
// of a recording with them (no progress line), and the object counters'
// consistency after a run.
#include <gtest/gtest.h>

#include <filesystem>

#include "core/common/data_paths.h"
#include "core/pipeline/dataset_runner.h"
#include "core/slam/slam_stats.h"

namespace orbatlas::test {

inline std::filesystem::path stereo_settings() { return shipped_config_dir() / "euroc" / "stereo.yaml"; }

inline DatasetRunOptions options_for(const std::filesystem::path& dataset) {
  DatasetRunOptions o;
  o.settings = stereo_settings();
  o.dataset = dataset;
  o.show_progress = false;
  return o;
}

// Objects alive are exactly those the maps hold, and every culled object was freed.
inline void expect_counters_consistent(const SlamStats& s) {
  EXPECT_EQ(s.keyframe_objects.alive(), s.keyframes);
  EXPECT_EQ(s.mappoint_objects.alive(), s.mappoints);
  EXPECT_EQ(s.keyframe_objects.reclaimed, s.keyframe_objects.culled);
  EXPECT_EQ(s.mappoint_objects.reclaimed, s.mappoint_objects.culled);
  EXPECT_EQ(s.keyframe_objects.created, s.keyframe_objects.culled + s.keyframes);
  EXPECT_EQ(s.mappoint_objects.created, s.mappoint_objects.culled + s.mappoints);
}

}  // namespace orbatlas::test
