// Tracking's wait for local mapping to adjust its newest keyframe
// (TrackerOptions::max_mapping_wait_ms): on a stereo run with and without a
// bound, and a wait cut at its bound taken up by the next frame.
#include <gtest/gtest.h>

#include <chrono>
#include <memory>
#include <opencv2/imgcodecs.hpp>
#include <thread>
#include <utility>
#include <vector>

#include "core/slam/slam_system.h"
#include "core/tracking/keyframe_sink.h"
#include "core/tracking/stereo_frontend.h"
#include "core/tracking/tracker.h"
#include "core/vocabulary/default_vocabulary.h"
#include "tests/support/slam_test_clip.h"
#include "tests/support/stereo_slam_runs.h"

namespace orbatlas {
namespace {

using test::stereo_settings;

// TrackerOptions::max_mapping_wait_ms: the frame after each keyframe waits for
// local mapping to adjust it. A bound that is never reached: one wait per
// keyframe but the last (the clip ends), none cut; off (the default): none.
// MH_04's fast flight makes a keyframe every few frames.
TEST(SlamSystem, TheFrameAfterAKeyframeWaitsForItsAdjustmentWhenAsked) {
  const auto clip = test::simulated_clip("MH_04", 20.0, 3.0);
  test::ClipCleanup cleanup{clip};
  const auto frames = test::stereo_frames(clip);
  const SlamSettings settings = read_settings(stereo_settings(), SensorType::kStereo);
  const Vocabulary vocabulary = Vocabulary::load(default_vocabulary_path());
  for (const double wait_ms : {10000.0, 0.0}) {
    SlamSystemOptions o;
    o.tracker.max_mapping_wait_ms = wait_ms;
    Atlas atlas;
    SlamSystem slam(atlas, settings, vocabulary, o);
    std::size_t tracked = 0;
    bool last_made_keyframe = false;
    for (const auto& f : frames) {
      const TrackResult r = slam.process(f.t_ns, cv::imread(f.left.string(), cv::IMREAD_GRAYSCALE),
                                         cv::imread(f.right.string(), cv::IMREAD_GRAYSCALE));
      tracked += r.tracked ? 1 : 0;
      last_made_keyframe = r.keyframe;
    }
    slam.finish();
    const SlamStats stats = slam.stats();
    EXPECT_EQ(tracked, frames.size());
    ASSERT_GT(stats.keyframes_made, 2u);
    if (wait_ms > 0.0) {
      EXPECT_EQ(stats.mapping_wait_ms.count(), stats.keyframes_made - (last_made_keyframe ? 1 : 0));
      EXPECT_EQ(stats.mapping_waits_cut, 0u);
    } else {
      EXPECT_EQ(stats.mapping_wait_ms.count(), 0u);
    }
  }
}

// A sink whose mapping never adjusts in time: each of the first `cuts` waits
// runs to its bound (or, `paused`, ends at once, as a paused mapping answers)
// and reports the keyframe not adjusted; later waits find it adjusted.
class SlowMappingSink final : public KeyframeSink {
 public:
  SlowMappingSink(int cuts, bool paused) : cuts_(cuts), paused_(paused) {}
  bool idle(MapId) const override { return true; }
  std::size_t queued(MapId) const override { return 0; }
  bool accepting(MapId) const override { return true; }
  void insert(std::shared_ptr<KeyFrame> keyframe) override { keyframes.push_back(std::move(keyframe)); }
  void interrupt_optimization(MapId) override {}
  bool wait_until_adjusted(MapId, std::chrono::milliseconds at_most) override {
    ++waits;
    if (cuts_ == 0) return true;
    --cuts_;
    if (!paused_) std::this_thread::sleep_for(at_most);  // a timed wait that runs out
    return false;
  }
  std::vector<std::shared_ptr<KeyFrame>> keyframes;
  int waits = 0;

 private:
  int cuts_;
  bool paused_;
};

// A wait cut at its bound is taken up by the next frame (each frame waits at
// most the bound) until the keyframe is adjusted; a wait that ends at once
// (mapping paused) is not taken up.
TEST(Tracker, AWaitCutAtItsBoundIsTakenUpByTheNextFrame) {
  const auto clip = test::simulated_clip("MH_01", 40.0, 0.5);
  test::ClipCleanup cleanup{clip};
  const auto frames = test::stereo_frames(clip);
  ASSERT_GE(frames.size(), 5u);
  const SlamSettings settings = read_settings(stereo_settings(), SensorType::kStereo);
  const Vocabulary vocabulary = Vocabulary::load(default_vocabulary_path());
  for (const bool paused : {false, true}) {
    StereoFrontend frontend(settings, false);
    Atlas atlas;
    SlowMappingSink sink(2, paused);
    TrackerOptions options;
    options.max_mapping_wait_ms = 5.0;
    Tracker tracker(atlas, vocabulary, sink, frontend.frame_camera(), frontend.calibration().T_b_c, options);
    const auto frame = [&](std::size_t i) {
      return frontend.make_frame(frames[i].t_ns, cv::imread(frames[i].left.string(), cv::IMREAD_GRAYSCALE),
                                 cv::imread(frames[i].right.string(), cv::IMREAD_GRAYSCALE));
    };
    EXPECT_FALSE(tracker.wait_for_mapping().has_value());  // no keyframe yet
    ASSERT_TRUE(tracker.track(frame(0)).keyframe);         // the map's first keyframe
    const auto first = tracker.wait_for_mapping();         // cut
    ASSERT_TRUE(first.has_value());
    const bool second_made_keyframe = tracker.track(frame(1)).keyframe;
    const auto second = tracker.wait_for_mapping();
    if (paused) {
      EXPECT_LT(*first, options.max_mapping_wait_ms);
      EXPECT_EQ(second.has_value(), second_made_keyframe) << "a paused mapping's answer is not waited on again";
    } else {
      EXPECT_GE(*first, options.max_mapping_wait_ms);
      ASSERT_TRUE(second.has_value()) << "the cut wait is taken up by the next frame";
      EXPECT_GE(*second, options.max_mapping_wait_ms);  // cut again
      tracker.track(frame(2));
      const auto third = tracker.wait_for_mapping();  // adjusted now
      ASSERT_TRUE(third.has_value());
      EXPECT_LT(*third, options.max_mapping_wait_ms);
      EXPECT_EQ(tracker.mapping_waits_cut(), 2u);
      const bool fourth_made_keyframe = tracker.track(frame(3)).keyframe;
      EXPECT_EQ(tracker.wait_for_mapping().has_value(), fourth_made_keyframe) << "nothing left to wait for";
      EXPECT_EQ(sink.waits, fourth_made_keyframe ? 4 : 3);
    }
  }
}

}  // namespace
}  // namespace orbatlas
