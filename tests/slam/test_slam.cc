// Stereo SLAM end to end on simulated Machine Hall clips: accuracy against the
// simulator's exact ground truth, the reclamation counters, the two culling
// schemes, two atlases side by side, and bad input.
#include <gtest/gtest.h>

#include <chrono>
#include <fstream>
#include <thread>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/common/data_paths.h"
#include "core/common/error.h"
#include "core/io/euroc_reader.h"
#include "core/pipeline/dataset_runner.h"
#include "wire/run_report_json.h"
#include "core/slam/slam_tuning.h"
#include "core/tracking/keyframe_sink.h"
#include "core/tracking/stereo_frontend.h"
#include "core/tracking/tracker.h"
#include "core/vocabulary/default_vocabulary.h"
#include "tests/support/slam_test_clip.h"

namespace orbatlas {
namespace {

std::filesystem::path stereo_settings() { return shipped_config_dir() / "euroc" / "stereo.yaml"; }

DatasetRunOptions options_for(const std::filesystem::path& dataset) {
  DatasetRunOptions o;
  o.settings = stereo_settings();
  o.dataset = dataset;
  o.show_progress = false;
  return o;
}

// Objects alive are exactly those the maps hold, and every culled object was freed.
void expect_counters_consistent(const SlamStats& s) {
  EXPECT_EQ(s.keyframe_objects.alive(), s.keyframes);
  EXPECT_EQ(s.mappoint_objects.alive(), s.mappoints);
  EXPECT_EQ(s.keyframe_objects.reclaimed, s.keyframe_objects.culled);
  EXPECT_EQ(s.mappoint_objects.reclaimed, s.mappoint_objects.culled);
  EXPECT_EQ(s.keyframe_objects.created, s.keyframe_objects.culled + s.keyframes);
  EXPECT_EQ(s.mappoint_objects.created, s.mappoint_objects.culled + s.mappoints);
}

TEST(SlamSystem, TenSecondClipTracksWithinFourMillimetres) {
  const auto clip = test::simulated_clip("MH_01", 40.0, 10.0);
  test::ClipCleanup cleanup{clip};
  const DatasetRunReport r = run_dataset(options_for(clip));
  EXPECT_EQ(r.stats.frames, 201u);
  EXPECT_EQ(r.stats.tracked, r.stats.frames);
  EXPECT_EQ(r.stats.maps, 1u);
  EXPECT_EQ(r.trajectory.size(), r.stats.tracked);
  ASSERT_TRUE(r.ate_rmse_m.has_value());
  EXPECT_LT(*r.ate_rmse_m, 0.004);  // measured 0.0020 m
  std::printf("10 s clip: ATE %.4f m, %zu keyframes (%zu culled), %zu map points, tracking p50 %.1f ms\n",
              *r.ate_rmse_m, r.stats.keyframes, r.stats.mapping.culled_keyframes, r.stats.mappoints,
              percentiles(r.stats.tracking_ms).p50);
  EXPECT_GE(r.stats.keyframes, 5u);
  // No part of this clip is revisited: place recognition runs but closes no loop.
  EXPECT_TRUE(r.stats.loop_closing);
  EXPECT_GT(r.stats.loop.keyframes, 0u);
  EXPECT_LE(r.stats.loop.keyframes + r.stats.loop.keyframes_skipped, r.stats.mapping.keyframes);
  EXPECT_EQ(r.stats.loop.loops.size(), 0u);
  EXPECT_GT(r.stats.mapping.points_triangulated, 0u);
  expect_counters_consistent(r.stats);
  // The JSON carries the keys the issue lists.
  const auto j = to_json(r);
  for (const char* key : {"frames", "tracked", "lost", "maps", "keyframes", "mappoints", "tracking_ms",
                          "local_mapping_ms_per_kf", "local_ba_ms", "culling_ms_per_kf", "peak_rss_mb", "objects",
                          "late_frames", "loops", "loop_closing", "worker_errors", "worker_errors_by", "slot_races"})
    EXPECT_TRUE(j.contains(key)) << key;
  EXPECT_EQ(j["objects"]["mappoints"]["reclaimed"].get<std::uint64_t>(), r.stats.mappoint_objects.reclaimed);
  // The live poses: what track() returned for each tracked frame, in its order,
  // scored beside the final trajectory, both in the stats.
  ASSERT_EQ(r.live_trajectory.size(), r.stats.tracked);
  ASSERT_EQ(r.live_maps.size(), r.live_trajectory.size());
  for (std::size_t i = 0; i < r.live_trajectory.size(); ++i)
    ASSERT_EQ(r.live_trajectory[i].t_ns, r.trajectory[i].t_ns) << i;
  ASSERT_TRUE(r.live_ate_rmse_m.has_value());
  std::printf("10 s clip: live ATE %.4f m, final %.4f m\n", *r.live_ate_rmse_m, *r.ate_rmse_m);
  EXPECT_LT(*r.live_ate_rmse_m, 0.004);  // measured 0.0018 m (the final 0.0017 m)
  EXPECT_EQ(j["live_ate_rmse_m"].get<double>(), *r.live_ate_rmse_m);
  EXPECT_EQ(j["ate_rmse_m"].get<double>(), *r.ate_rmse_m);
  EXPECT_EQ(j["live_poses"].get<std::size_t>(), r.stats.tracked);
  EXPECT_DOUBLE_EQ(j["live_fraction"].get<double>(), 1.0);
}

// The optional final global BA (orbatlas run --final-ba): it covers every
// keyframe of the map, and on the same deterministic run the trajectory it
// leaves is no worse (on full sequences it is what brings MH_04/MH_05 under
// 1 cm, docs/benchmarks.md).
TEST(SlamSystem, FinalGlobalBundleAdjustmentCoversTheMapAndDoesNotHurt) {
  const auto clip = test::simulated_clip("MH_01", 40.0, 10.0);
  test::ClipCleanup cleanup{clip};
  DatasetRunReport runs[2];
  for (int i = 0; i < 2; ++i) {
    DatasetRunOptions o = options_for(clip);
    o.slam.synchronous_mapping = true;  // the same map before the final BA
    o.slam.final_global_ba = i == 1;
    runs[i] = run_dataset(o);
    ASSERT_TRUE(runs[i].ate_rmse_m.has_value());
  }
  EXPECT_EQ(runs[0].stats.final_ba_keyframes, 0u);
  EXPECT_EQ(runs[1].stats.final_ba_keyframes, runs[1].stats.keyframes);
  EXPECT_GT(runs[1].stats.final_ba_s, 0.0);
  EXPECT_EQ(runs[0].stats.keyframes, runs[1].stats.keyframes);
  EXPECT_LT(*runs[1].ate_rmse_m, *runs[0].ate_rmse_m + 0.0005);
  EXPECT_LT(*runs[1].ate_rmse_m, 0.004);  // measured 0.0020 m
  std::printf("ATE without the final global BA %.4f m, with it %.4f m (%zu keyframes, %.2f s)\n", *runs[0].ate_rmse_m,
              *runs[1].ate_rmse_m, runs[1].stats.final_ba_keyframes, runs[1].stats.final_ba_s);
}

TEST(SlamSystem, BothCullingSchemesTakeTheSameDecisions) {
  const auto clip = test::simulated_clip("MH_01", 40.0, 10.0);
  test::ClipCleanup cleanup{clip};
  DatasetRunReport runs[2];
  const CullingScheme schemes[2] = {CullingScheme::kScan, CullingScheme::kIncremental};
  for (int i = 0; i < 2; ++i) {
    DatasetRunOptions o = options_for(clip);
    o.slam.synchronous_mapping = true;  // deterministic: both runs see the same maps
    o.slam.mapper.culling.scheme = schemes[i];
    o.slam.mapper.culling.compare_schemes = true;
    // At ORB-SLAM's 90% a 10 s clip culls nothing (keyframes are few and fresh);
    // at 50% both decisions occur, and the schemes must agree at any threshold.
    o.slam.mapper.culling.redundancy.redundant_fraction = 0.5;
    runs[i] = run_dataset(o);
    EXPECT_EQ(runs[i].stats.mapping.culling_disagreements, 0u) << culling_scheme_name(schemes[i]);
    EXPECT_GT(runs[i].stats.mapping.culling_candidates, 0u);
    expect_counters_consistent(runs[i].stats);
  }
  EXPECT_GT(runs[0].stats.mapping.culled_keyframes, 0u) << "no keyframe was culled: the test shows nothing";
  EXPECT_GT(runs[0].stats.mapping.culling_candidates, runs[0].stats.mapping.culled_keyframes)
      << "every candidate was culled: the test shows only one kind of decision";
  EXPECT_EQ(runs[0].stats.mapping.culled_keyframes, runs[1].stats.mapping.culled_keyframes);
  EXPECT_EQ(runs[0].stats.mapping.culled_keyframes_digest, runs[1].stats.mapping.culled_keyframes_digest);
  EXPECT_EQ(runs[0].stats.keyframes, runs[1].stats.keyframes);
  EXPECT_EQ(runs[0].stats.mappoints, runs[1].stats.mappoints);
  ASSERT_EQ(runs[0].trajectory.size(), runs[1].trajectory.size());
  // The same decisions give the same map; the solvers' threads may round
  // differently from run to run (seen once under load: equal to 6 digits).
  EXPECT_LT((runs[0].trajectory.back().pose.t - runs[1].trajectory.back().pose.t).norm(), 1e-6);
  std::printf("culling per keyframe: scan %.4f ms, incremental %.4f ms (%zu candidates, %zu culled)\n",
              percentiles(runs[0].stats.mapping.culling_scan_ms).mean,
              percentiles(runs[1].stats.mapping.culling_incremental_ms).mean, runs[0].stats.mapping.culling_candidates,
              runs[0].stats.mapping.culled_keyframes);
}

TEST(SlamSystem, TwoAtlasesInOneProcessRunSideBySide) {
  const auto clip = test::simulated_clip("MH_01", 40.0, 3.0);
  test::ClipCleanup cleanup{clip};
  const auto frames = test::stereo_frames(clip);
  const SlamSettings settings = read_settings(stereo_settings(), SensorType::kStereo);
  const Vocabulary vocabulary = Vocabulary::load(default_vocabulary_path());
  SlamSystemOptions o;
  o.synchronous_mapping = true;
  Atlas a, b;
  SlamSystem sa(a, settings, vocabulary, o), sb(b, settings, vocabulary, o);
  for (const auto& f : frames) {
    const cv::Mat l = cv::imread(f.left.string(), cv::IMREAD_GRAYSCALE);
    const cv::Mat r = cv::imread(f.right.string(), cv::IMREAD_GRAYSCALE);
    EXPECT_TRUE(sa.process(f.t_ns, l, r).tracked);
    EXPECT_TRUE(sb.process(f.t_ns, l, r).tracked);
  }
  sa.finish();
  sb.finish();
  // Each atlas numbers its own objects from the start, and both saw the same input.
  const auto ka = a.active_map()->keyframes(), kb = b.active_map()->keyframes();
  ASSERT_EQ(ka.size(), kb.size());
  for (std::size_t i = 0; i < ka.size(); ++i) EXPECT_EQ(ka[i]->id(), kb[i]->id());
  EXPECT_EQ(a.counters()->map_points().created, b.counters()->map_points().created);
  EXPECT_NE(a.counters().get(), b.counters().get());
  const auto ta = sa.trajectory(), tb = sb.trajectory();
  ASSERT_EQ(ta.size(), frames.size());
  ASSERT_EQ(ta.size(), tb.size());
  EXPECT_EQ(ta.back().T_w_b.t, tb.back().T_w_b.t);
  expect_counters_consistent(sa.stats());
  expect_counters_consistent(sb.stats());
}

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
    std::printf("wait bound %.0f ms: %zu keyframes, %zu waits (mean %.2f ms), %zu cut\n", wait_ms, stats.keyframes_made,
                stats.mapping_wait_ms.count(), stats.mapping_wait_ms.mean(), stats.mapping_waits_cut);
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
  std::printf("left camera alone: %zu of %zu frames tracked, ATE %.4f m (Sim3)\n", r.stats.tracked, r.stats.frames,
              *r.ate_rmse_m);
  EXPECT_LT(*r.ate_rmse_m, 0.013);  // measured 0.0063 m (56 of 61 frames)

  options.settings = shipped_config_dir() / "euroc" / "mono.yaml";
  options.sensor = SensorType::kMonocularInertial;
  EXPECT_THROW(run_dataset(options), Error);  // not a stereo config
}

}  // namespace
}  // namespace orbatlas

namespace orbatlas {
namespace {

// Kidnapping with a small map: tracking fails at the jump, the map (at most 10
// keyframes) is given up at once (LOST), and a new map is started in the atlas
// from the next frame; the first map stays, and poses come out in both.
TEST(SlamSystem, LostTrackingStartsANewMapInTheAtlas) {
  const auto before = test::simulated_clip("MH_01", 40.0, 2.0);
  const auto after = test::simulated_clip("MH_01", 125.0, 2.0);
  test::ClipCleanup c1{before}, c2{after};
  std::vector<DatasetFrame> frames = test::stereo_frames(before);
  for (const auto& f : test::stereo_frames(after)) frames.push_back(f);
  const SlamSettings settings = read_settings(stereo_settings(), SensorType::kStereo);
  const Vocabulary vocabulary = Vocabulary::load(default_vocabulary_path());
  SlamSystemOptions o;
  o.synchronous_mapping = true;
  Atlas atlas;
  SlamSystem slam(atlas, settings, vocabulary, o);
  std::vector<TrackResult> results;
  for (const auto& f : frames)
    results.push_back(slam.process(f.t_ns, cv::imread(f.left.string(), cv::IMREAD_GRAYSCALE),
                                   cv::imread(f.right.string(), cv::IMREAD_GRAYSCALE)));
  slam.finish();
  // Across the hall nothing is recognised: a few frames of failed
  // relocalisation (SlamSystemOptions::new_map_after_failed_relocalizations),
  // then a new map, tracked from its first frame on.
  const std::size_t jump = test::stereo_frames(before).size();
  for (std::size_t i = 0; i < jump; ++i) EXPECT_TRUE(results[i].tracked) << "frame " << i;
  EXPECT_FALSE(results[jump].tracked) << "the jump across the hall went unnoticed";
  EXPECT_EQ(results[jump].state, TrackingState::kRecentlyLost);
  const MapId first_map = results[0].map;
  std::size_t resumed = jump;
  while (resumed < results.size() && !results[resumed].tracked) ++resumed;
  ASSERT_LT(resumed, results.size());
  EXPECT_LE(resumed - jump, static_cast<std::size_t>(o.new_map_after_failed_relocalizations) + 1);
  EXPECT_EQ(results[resumed - 1].state, TrackingState::kLost);
  EXPECT_NE(results[resumed].map, first_map);  // initialised the new map
  for (std::size_t i = resumed; i < results.size(); ++i) EXPECT_TRUE(results[i].tracked) << "frame " << i;
  const SlamStats s = slam.stats();
  EXPECT_EQ(s.maps, 2u);
  EXPECT_EQ(s.maps_started, 2u);
  EXPECT_EQ(s.lost, resumed - jump);
  EXPECT_GT(atlas.map(first_map)->keyframe_count(), 0u);
  const auto trajectory = slam.trajectory();
  EXPECT_EQ(trajectory.size(), results.size() - s.lost);
  EXPECT_EQ(trajectory.front().map, first_map);
  EXPECT_EQ(trajectory.back().map, results.back().map);
  expect_counters_consistent(s);
}

}  // namespace
}  // namespace orbatlas
