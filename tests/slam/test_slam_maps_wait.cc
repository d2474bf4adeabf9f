// The bound on a frame's wait for the atlas's maps
// (SlamSystemOptions::max_maps_wait_ms): while an edit holds the maps past it,
// the frame is answered untracked at once and tracking goes on at the next.
#include <gtest/gtest.h>

#include <chrono>
#include <future>
#include <opencv2/imgcodecs.hpp>

#include "core/slam/slam_system.h"
#include "core/vocabulary/default_vocabulary.h"
#include "tests/support/slam_test_clip.h"
#include "tests/support/stereo_slam_runs.h"

namespace orbatlas {
namespace {

TEST(SlamSystem, AFrameHeldPastItsMapsWaitIsAnsweredUntrackedAndTrackingGoesOn) {
  const auto clip = test::simulated_clip("MH_01", 40.0, 1.0);
  test::ClipCleanup cleanup{clip};
  const auto frames = test::stereo_frames(clip);
  ASSERT_GE(frames.size(), 12u);
  const SlamSettings settings = read_settings(test::stereo_settings(), SensorType::kStereo);
  const Vocabulary vocabulary = Vocabulary::load(default_vocabulary_path());
  SlamSystemOptions o;
  o.max_maps_wait_ms = 40.0;
  Atlas atlas;
  SlamSystem slam(atlas, settings, vocabulary, o);
  const auto process = [&](std::size_t i) {
    return slam.process(frames[i].t_ns, cv::imread(frames[i].left.string(), cv::IMREAD_GRAYSCALE),
                        cv::imread(frames[i].right.string(), cv::IMREAD_GRAYSCALE));
  };
  for (std::size_t i = 0; i < 5; ++i) ASSERT_TRUE(process(i).tracked);
  {
    // An edit holds the maps (a merge being applied, say) across two frames.
    const auto edit = atlas.lock_maps_exclusive();
    for (std::size_t i = 5; i < 7; ++i) {
      const auto start = std::chrono::steady_clock::now();
      const TrackResult held = process(i);
      const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
      EXPECT_TRUE(held.maps_busy);
      EXPECT_FALSE(held.tracked);
      EXPECT_EQ(held.t_ns, frames[i].t_ns);
      EXPECT_EQ(held.state, TrackingState::kOk) << "the tracker has not seen the frame";
      EXPECT_GE(held.maps_wait_ms, o.max_maps_wait_ms);
      EXPECT_LT(held.maps_wait_ms, 2.0 * o.max_maps_wait_ms);
      EXPECT_LT(ms, 2.0 * o.max_maps_wait_ms + 60.0) << "the front end's time and the bound, no more";
    }
  }
  // The maps are free again: the next frames track on from the last one tracked.
  for (std::size_t i = 7; i < frames.size(); ++i) {
    const TrackResult r = process(i);
    EXPECT_TRUE(r.tracked) << "frame " << i;
    EXPECT_FALSE(r.maps_busy);
  }
  slam.finish();
  EXPECT_EQ(slam.stats().maps_busy_frames, 2u);
  EXPECT_EQ(slam.stats().frames, frames.size());
}

// Without a bound (the default, offline runs) the frame waits for the edit.
TEST(SlamSystem, WithoutAMapsWaitBoundAFrameWaitsForTheEdit) {
  const auto clip = test::simulated_clip("MH_01", 40.0, 0.5);
  test::ClipCleanup cleanup{clip};
  const auto frames = test::stereo_frames(clip);
  ASSERT_GE(frames.size(), 4u);
  const SlamSettings settings = read_settings(test::stereo_settings(), SensorType::kStereo);
  const Vocabulary vocabulary = Vocabulary::load(default_vocabulary_path());
  Atlas atlas;
  SlamSystem slam(atlas, settings, vocabulary, SlamSystemOptions{});
  const auto process = [&](std::size_t i) {
    return slam.process(frames[i].t_ns, cv::imread(frames[i].left.string(), cv::IMREAD_GRAYSCALE),
                        cv::imread(frames[i].right.string(), cv::IMREAD_GRAYSCALE));
  };
  ASSERT_TRUE(process(0).tracked);
  auto edit = atlas.lock_maps_exclusive();
  auto held = std::async(std::launch::async, [&] { return process(1); });
  EXPECT_EQ(held.wait_for(std::chrono::milliseconds(200)), std::future_status::timeout) << "it waits for the edit";
  edit.unlock();
  const TrackResult r = held.get();
  EXPECT_TRUE(r.tracked);
  EXPECT_FALSE(r.maps_busy);
  EXPECT_GT(r.maps_wait_ms, 100.0);  // the 200 ms hold less the frame's front end
  slam.finish();
  EXPECT_EQ(slam.stats().maps_busy_frames, 0u);
}

}  // namespace
}  // namespace orbatlas
