// What stereo SLAM and the dataset runner take and refuse: bad frames as
// DataErrors with the session going on, the Orbatlas.* tuning keys of a
// settings file, unreadable images, single-camera settings, and the left
// camera of a stereo config alone.
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <iterator>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>

#include "core/common/data_paths.h"
#include "core/common/error.h"
#include "core/io/euroc_reader.h"
#include "core/pipeline/dataset_runner.h"
#include "core/slam/slam_tuning.h"
#include "core/vocabulary/default_vocabulary.h"
#include "tests/support/slam_test_clip.h"
#include "tests/support/stereo_slam_runs.h"

namespace orbatlas {
namespace {

using test::options_for;
using test::stereo_settings;

TEST(SlamSystem, BadFramesAreDataErrorsAndTheSessionGoesOn) {
  const auto clip = test::simulated_clip("MH_01", 40.0, 1.0);
  test::ClipCleanup cleanup{clip};
  const auto frames = test::stereo_frames(clip);
  ASSERT_GE(frames.size(), 6u);
  const SlamSettings settings = read_settings(stereo_settings(), SensorType::kStereo);
  const Vocabulary vocabulary = Vocabulary::load(default_vocabulary_path());
  Atlas atlas;
  SlamSystem slam(atlas, settings, vocabulary);
  auto load = [&](std::size_t i, cv::Mat& l, cv::Mat& r) {
    l = cv::imread(frames[i].left.string(), cv::IMREAD_GRAYSCALE);
    r = cv::imread(frames[i].right.string(), cv::IMREAD_GRAYSCALE);
  };
  cv::Mat l, r;
  for (std::size_t i = 0; i < 3; ++i) {
    load(i, l, r);
    EXPECT_TRUE(slam.process(frames[i].t_ns, l, r).tracked);
  }
  load(3, l, r);
  EXPECT_THROW(slam.process(frames[1].t_ns, l, r), DataError);          // timestamp going backwards
  EXPECT_THROW(slam.process(frames[3].t_ns, cv::Mat(), r), DataError);  // empty image
  cv::Mat small;
  cv::resize(l, small, cv::Size(l.cols / 2, l.rows / 2));
  EXPECT_THROW(slam.process(frames[3].t_ns, small, small), DataError);  // wrong size
  cv::Mat deep;
  l.convertTo(deep, CV_16U);
  EXPECT_THROW(slam.process(frames[3].t_ns, deep, r), DataError);  // 16-bit
  for (std::size_t i = 3; i < frames.size(); ++i) {
    load(i, l, r);
    EXPECT_TRUE(slam.process(frames[i].t_ns, l, r).tracked) << "frame " << i;
  }
  slam.finish();
  EXPECT_THROW(slam.process(frames.back().t_ns + 1, l, r), Error);  // finished
  EXPECT_EQ(slam.trajectory().size(), frames.size());
}

// The Orbatlas.* keys of a settings file tune the engine: each known key sets its
// option (over what SlamSystem derives from the camera), anything else is a
// DataError naming the key, and a bad value changes nothing.
TEST(SlamTuning, SettingsKeysSetTheOptionsAndBadOnesAreRefused) {
  std::ifstream in(stereo_settings());
  std::string text((std::istreambuf_iterator<char>(in)), {});
  text +=
      "\nOrbatlas.Tracker.MinInliers: 42\nOrbatlas.LocalMapping.FusionRadius: 2.5\n"
      "Orbatlas.LoopClosing.Enabled: 0\nOrbatlas.Tracker.MaxFramesBetweenKeyframes: 7\n";
  const SlamSettings settings = read_settings_text(text, "tuned.yaml", SensorType::kStereo);
  ASSERT_EQ(settings.orbatlas.size(), 4u);
  EXPECT_EQ(settings.orbatlas.at("Tracker.MinInliers"), 42.0);

  SlamSystemOptions options;
  apply_slam_tuning(settings.orbatlas, options);
  EXPECT_EQ(options.tracker.min_inliers, 42);
  EXPECT_FLOAT_EQ(options.mapper.fusion_radius, 2.5f);
  EXPECT_FALSE(options.loop_closing);
  EXPECT_EQ(slam_tuning_values(options).at("Tracker.MaxFramesBetweenKeyframes"), 7.0);

  const auto refused = [](const std::map<std::string, double>& tuning) {
    SlamSystemOptions o;
    try {
      apply_slam_tuning(tuning, o);
    } catch (const DataError& e) {
      EXPECT_EQ(o.tracker.min_inliers, SlamSystemOptions{}.tracker.min_inliers) << "changed before refusing";
      return std::string(e.what());
    }
    return std::string("<accepted>");
  };
  EXPECT_NE(refused({{"Tracker.MinInliers", 50}, {"Tracker.NoSuchKey", 1}}).find("Orbatlas.Tracker.NoSuchKey"),
            std::string::npos);
  EXPECT_NE(refused({{"Tracker.MinInliers", 1e9}}).find("must be in"), std::string::npos);
  EXPECT_NE(refused({{"Tracker.MinInliers", 30.5}}).find("whole number"), std::string::npos);
  EXPECT_NE(refused({{"LoopClosing.Enabled", 2}}).find("must be in"), std::string::npos);
  EXPECT_NE(refused({{"Tracker.MinInliers", -1}}).find("'Orbatlas.Tracker.MinInliers'"), std::string::npos);
  // A value in its range that the resulting options refuse (their check()) names its key.
  SlamSystemOptions localizing;
  localizing.tracker.localization_only = true;
  try {
    apply_slam_tuning({{"Tracker.MinInliers", 40}, {"Tracker.Relocalization", 0}}, localizing);
    ADD_FAILURE() << "localisation without a relocaliser accepted";
  } catch (const DataError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("'Orbatlas.Tracker.Relocalization' = 0"), std::string::npos) << what;
    EXPECT_EQ(what.find("MinInliers"), std::string::npos) << what;
    EXPECT_NE(what.find("relocalization must be on"), std::string::npos) << what;
  }
  EXPECT_TRUE(localizing.relocalization) << "changed before refusing";
  // Options out of range before any key applies: check()'s Error, not the settings' fault.
  SlamSystemOptions broken;
  broken.tracker.th_depth_m = -1.0;
  try {
    apply_slam_tuning({{"Tracker.MinInliers", 40}}, broken);
    ADD_FAILURE() << "out-of-range options accepted";
  } catch (const DataError& e) {
    ADD_FAILURE() << "the settings were blamed: " << e.what();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("th_depth_m"), std::string::npos) << e.what();
  }
  EXPECT_THROW(read_settings_text(text + "Orbatlas.Tracker.MinInliers2: many\n", "bad.yaml", SensorType::kStereo),
               DataError);  // not a number

  // docs/settings.md lists every key.
  std::ifstream doc(shipped_config_dir().parent_path() / "docs" / "settings.md");
  const std::string docs((std::istreambuf_iterator<char>(doc)), {});
  for (const SlamTuningKey& k : slam_tuning_keys())
    EXPECT_NE(docs.find("`Orbatlas." + k.key + "`"), std::string::npos) << "docs/settings.md lacks Orbatlas." << k.key;

  // A session built from these settings runs with them; an unknown key stops it
  // before its first frame.
  const Vocabulary vocabulary = Vocabulary::load(default_vocabulary_path());
  Atlas atlas;
  const SlamSystem tuned(atlas, settings, vocabulary);
  SlamSettings wrong = settings;
  wrong.orbatlas["Tracker.Typo"] = 1;
  Atlas other;
  EXPECT_THROW(SlamSystem(other, wrong, vocabulary), DataError);
}

// Orbatlas.Tracker.MaxKeyframeIntervalSeconds: while tracking holds, a keyframe
// at least that often (what an IMU's sessions get by default); a stereo rig
// hovering in MH_01 otherwise goes longer without one.
TEST(SlamSystem, TheKeyframeIntervalKeyBoundsTheTimeBetweenKeyframes) {
  const auto clip = test::simulated_clip("MH_01", 40.0, 3.0);
  test::ClipCleanup cleanup{clip};
  const auto frames = test::stereo_frames(clip);
  const Vocabulary vocabulary = Vocabulary::load(default_vocabulary_path());
  SlamSystemOptions o;
  o.synchronous_mapping = true;  // local mapping never has keyframes queued
  auto longest_gap_s = [&](double interval_s) {
    SlamSettings settings = read_settings(stereo_settings(), SensorType::kStereo);
    if (interval_s > 0.0) settings.orbatlas["Tracker.MaxKeyframeIntervalSeconds"] = interval_s;
    Atlas atlas;
    SlamSystem slam(atlas, settings, vocabulary, o);
    TimestampNs last_keyframe_ns = frames.front().t_ns;
    double longest = 0.0;
    for (const auto& f : frames) {
      const TrackResult r = slam.process(f.t_ns, cv::imread(f.left.string(), cv::IMREAD_GRAYSCALE),
                                         cv::imread(f.right.string(), cv::IMREAD_GRAYSCALE));
      EXPECT_TRUE(r.tracked);
      if (!r.keyframe) continue;
      longest = std::max(longest, ns_to_s(f.t_ns - last_keyframe_ns));
      last_keyframe_ns = f.t_ns;
    }
    slam.finish();
    return std::max(longest, ns_to_s(frames.back().t_ns - last_keyframe_ns));  // and to the clip's end
  };
  const double without = longest_gap_s(0.0);
  const double with = longest_gap_s(0.25);
  EXPECT_GT(without, 2.0);        // measured: none in the 3-s clip
  EXPECT_LE(with, 0.25 + 0.051);  // the first frame at or past the interval (20 Hz)
}

TEST(DatasetRunner, UnreadableImageIsSkippedAndReported) {
  const auto clip = test::simulated_clip("MH_01", 40.0, 1.0);
  test::ClipCleanup cleanup{clip};
  const auto frames = test::stereo_frames(clip);
  { std::ofstream(frames[5].left, std::ios::trunc) << "not a png"; }
  const DatasetRunReport r = run_dataset(options_for(clip));
  EXPECT_EQ(r.skipped_frames, 1u);
  EXPECT_EQ(r.stats.frames, frames.size() - 1);
  EXPECT_EQ(r.stats.tracked, r.stats.frames);
}

TEST(DatasetRunner, TakesSingleCameraSettingsAndRejectsMissingDatasets) {
  EXPECT_THROW(run_dataset(options_for("/nonexistent/orbatlas/dataset")), Error);
  const Vocabulary vocabulary = Vocabulary::load(default_vocabulary_path());
  Atlas atlas;
  // A single camera maps (monocular SLAM), also with its IMU.
  const SlamSettings mono = read_settings(shipped_config_dir() / "euroc" / "mono.yaml");
  const SlamSystem slam(atlas, mono, vocabulary);
  EXPECT_TRUE(slam.monocular());
  EXPECT_FALSE(slam.inertial());
  EXPECT_EQ(slam.frontend().baseline(), 0.0);
  const SlamSettings mono_inertial = read_settings(shipped_config_dir() / "euroc" / "mono_inertial.yaml");
  const SlamSystem with_imu(atlas, mono_inertial, vocabulary);
  EXPECT_TRUE(with_imu.monocular());
  EXPECT_TRUE(with_imu.inertial());
}

// `--sensor mono`: the left camera of a stereo config alone, rectified as the
// rig's stereo maps are; the run reads cam0 only and scores with Sim(3). Only
// a stereo config gives a single camera this way.
TEST(DatasetRunner, TheLeftCameraOfAStereoConfigRunsAlone) {
  const auto clip = test::simulated_clip("MH_01", 50.0, 3.0);
  test::ClipCleanup cleanup{clip};
  DatasetRunOptions options = options_for(clip);
  options.sensor = SensorType::kMonocular;
  std::filesystem::remove_all(clip / "mav0" / "cam1");  // not read
  const DatasetRunReport r = run_dataset(options);
  EXPECT_TRUE(r.ate_sim3);
  EXPECT_EQ(r.stats.monocular_starts, 1u);
  EXPECT_GT(r.stats.tracked, r.stats.frames / 2);
  ASSERT_TRUE(r.ate_rmse_m.has_value());
  EXPECT_LT(*r.ate_rmse_m, 0.013);  // measured 0.0063 m (56 of 61 frames)

  options.settings = shipped_config_dir() / "euroc" / "mono.yaml";
  options.sensor = SensorType::kMonocularInertial;
  EXPECT_THROW(run_dataset(options), Error);  // not a stereo config
}

}  // namespace
}  // namespace orbatlas
