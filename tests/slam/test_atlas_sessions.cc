// The persistent atlas through the SLAM runner: a run stored with --atlas, a
// second run over the same place appending a session whose map is merged live
// into the first one (one map stored), and localisation
// of another flight through the stored place (MH_02) against the stored map (no keyframe added),
// measured in the stored map's own frame; a run with another camera rig keeps
// out of the stored map. Several recordings at once map one place together.
#include <gtest/gtest.h>

#include <unistd.h>

#include <fstream>
#include <functional>
#include <algorithm>
#include <iterator>
#include <set>
#include <string>

#include "core/common/data_paths.h"
#include "core/eval/evaluate.h"
#include "core/persistence/atlas_store.h"
#include "core/pipeline/dataset_runner.h"
#include "core/vocabulary/default_vocabulary.h"
#include "tests/support/slam_test_clip.h"

namespace orbatlas {
namespace {

DatasetRunOptions options_for(const std::filesystem::path& dataset, const std::filesystem::path& atlas) {
  DatasetRunOptions o;
  o.settings = shipped_config_dir() / "euroc" / "stereo.yaml";
  o.dataset = dataset;
  o.atlas = atlas;
  o.show_progress = false;
  return o;
}

TEST(AtlasSessions, RunsAppendSessionsAndLocalizationTracksInTheStoredMapFrame) {
  const auto clip = test::simulated_clip("MH_01", 40.0, 10.0);
  test::ClipCleanup cleanup{clip};
  const auto dir = std::filesystem::temp_directory_path() / ("orbatlas_test_sessions_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  test::ClipCleanup cleanup_dir{dir};
  const auto db = dir / "atlas.db";

  // Session 1 builds a map; session 2 (same file) starts one of its own, which
  // live merging joins to the stored map once it recognises the place.
  const DatasetRunReport first = run_dataset(options_for(clip, db));
  ASSERT_TRUE(first.session.has_value());
  ASSERT_TRUE(first.checkpoints.has_value());
  EXPECT_EQ(first.checkpoints->failures, 0u);
  EXPECT_GE(first.checkpoints->commits, 1u);
  const DatasetRunReport second = run_dataset(options_for(clip, db));
  EXPECT_EQ(second.loaded_maps, 1u);
  EXPECT_EQ(second.loaded_keyframes, first.stats.keyframes);
  ASSERT_TRUE(second.session.has_value());
  EXPECT_EQ(*second.session, *first.session + 1);
  ASSERT_EQ(second.stats.loop.merges.size(), 1u);
  EXPECT_EQ(second.stats.loop.merges.front().merge.target, 0u);
  EXPECT_EQ(second.stats.maps, 1u);

  const Vocabulary vocabulary = Vocabulary::load(default_vocabulary_path());
  MapId first_map = 0;
  TimestampNs first_keyframe_t = 0;
  {
    AtlasStore store = AtlasStore::open(db, vocabulary.hash());
    EXPECT_EQ(store.load_sessions().size(), 2u);
    EXPECT_EQ(store.load_trajectory(*first.session).size(), first.trajectory.size());
    EXPECT_EQ(store.load_trajectory(*second.session).size(), second.trajectory.size());
    Atlas atlas;
    const AtlasLoadReport loaded = store.load_atlas(atlas, &vocabulary);
    EXPECT_EQ(loaded.maps, 1u);
    EXPECT_EQ(loaded.keyframes, second.stats.keyframes);  // the joined map, as the second run ended
    const auto maps = atlas.maps();
    ASSERT_EQ(maps.size(), 1u);
    first_map = maps.front()->id();
    first_keyframe_t = maps.front()->keyframes().front()->timestamp_ns();
  }

  // Another flight through the stored place (MH_02 at 41-44 s passes 0.3 to
  // 0.9 m from where MH_01 was at 40-50 s), localised against the stored maps:
  // the database must not change.
  const auto again = dir / "again";
  sim::SimulationOptions so;
  so.sequence = "MH_02";
  so.out_dir = again;
  so.start_s = 41.0;
  so.duration_s = 3.0;
  so.show_progress = false;
  sim::simulate_sequence(so);
  const auto size_before = std::filesystem::file_size(db);
  DatasetRunOptions lo = options_for(again, db);
  lo.localize_only = true;
  const DatasetRunReport loc = run_dataset(lo);
  EXPECT_FALSE(loc.session.has_value());
  EXPECT_EQ(loc.stats.keyframes_made, 0u);
  EXPECT_EQ(std::filesystem::file_size(db), size_before);
  const double fraction = static_cast<double>(loc.trajectory.size()) / static_cast<double>(loc.stats.frames);
  EXPECT_GE(fraction, 0.9);

  // In the stored map's frame: the map's origin is the body at its first keyframe,
  // so ground truth maps into it through that pose (no alignment is fitted).
  const EurocDataset dataset = test::stereo_dataset(again);
  Trajectory gt;
  for (const auto& s : dataset.ground_truth) gt.push_back({s.t_ns, s.T_w_b});
  const EurocDataset original = test::stereo_dataset(clip);
  Trajectory gt_original;
  for (const auto& s : original.ground_truth) gt_original.push_back({s.t_ns, s.T_w_b});
  const auto T_w_origin = pose_at(gt_original, first_keyframe_t, 50'000'000);
  ASSERT_TRUE(T_w_origin.has_value());
  double sum2 = 0.0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < loc.trajectory.size(); ++i) {
    const auto T_w_b = pose_at(gt, loc.trajectory[i].t_ns, 50'000'000);
    if (!T_w_b) continue;
    const Pose3 expected = T_w_origin->inverse() * *T_w_b;
    sum2 += (expected.t - loc.trajectory[i].pose.t).squaredNorm();
    ++n;
    EXPECT_EQ(loc.trajectory_maps[i], first_map);
  }
  ASSERT_GT(n, 0u);
  const double ate = std::sqrt(sum2 / static_cast<double>(n));
  EXPECT_LT(ate, 0.008);  // measured 0.0037 m

  // A run with another rig (the same images, fx 1 px off): local mapping would
  // adjust the stored keyframes with the wrong camera, so it neither enters nor
  // merges into the stored map: a map of its own.
  std::ifstream in(shipped_config_dir() / "euroc" / "stereo.yaml");
  std::string yaml((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string fx = "Camera1.fx: 458.654";
  ASSERT_NE(yaml.find(fx), std::string::npos);
  yaml.replace(yaml.find(fx), fx.size(), "Camera1.fx: 459.654");
  const auto other_rig = dir / "other_rig.yaml";
  std::ofstream(other_rig) << yaml;
  DatasetRunOptions other = options_for(clip, db);
  other.settings = other_rig;
  const DatasetRunReport third = run_dataset(other);
  EXPECT_EQ(third.loaded_maps, 1u);
  EXPECT_TRUE(third.stats.loop.merges.empty());
  EXPECT_EQ(third.stats.maps, 2u);
  EXPECT_EQ(third.trajectory.size(), third.stats.frames);
  for (const MapId m : third.trajectory_maps) EXPECT_NE(m, first_map);
}

// Several recordings at once into one atlas (`orbatlas run --dataset A
// --dataset B`), without HTTP: two flights through one place, each its own
// session on its own thread, sharing one mapping. They end in one map (the
// second starts apart and is merged live while both run, or joins at once),
// both sessions are stored, and the two trajectories in that map agree with
// the ground truth of both under one alignment.
TEST(AtlasSessions, SeveralRecordingsAtOnceMapOnePlaceTogether) {
  const auto a = test::simulated_clip("MH_01", 40.0, 4.0);
  test::ClipCleanup cleanup_a{a};
  const auto b = test::simulated_clip("MH_02", 41.0, 3.0);
  test::ClipCleanup cleanup_b{b};
  const auto dir = std::filesystem::temp_directory_path() / ("orbatlas_test_several_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  test::ClipCleanup cleanup_dir{dir};
  const auto db = dir / "atlas.db";
  DatasetRunOptions options = options_for(a, db);
  options.realtime = true;  // both at the camera rate, as two devices
  const std::vector<DatasetRunReport> reports = run_datasets(options, {a, b});
  ASSERT_EQ(reports.size(), 2u);
  std::set<MapId> maps;
  Trajectory joint, truth;
  for (const auto& r : reports) {
    EXPECT_TRUE(r.failed.empty()) << r.failed;
    EXPECT_EQ(r.trajectory.size(), r.stats.frames);
    ASSERT_TRUE(r.ate_rmse_m.has_value());
    maps.insert(r.trajectory_maps.begin(), r.trajectory_maps.end());
    joint.insert(joint.end(), r.trajectory.begin(), r.trajectory.end());
  }
  EXPECT_EQ(maps.size(), 1u);
  ASSERT_TRUE(reports[0].session && reports[1].session);
  EXPECT_EQ(*reports[1].session, *reports[0].session + 1);
  for (const auto& clip : {a, b})
    for (const auto& s : test::stereo_dataset(clip).ground_truth) truth.push_back({s.t_ns, s.T_w_b});
  const auto by_time = [](const StampedPose& x, const StampedPose& y) { return x.t_ns < y.t_ns; };
  std::sort(joint.begin(), joint.end(), by_time);
  std::sort(truth.begin(), truth.end(), by_time);
  const double joint_ate = evaluate_trajectory(joint, truth).ate.rmse;
  EXPECT_LT(joint_ate, 2.0 * std::max(*reports[0].ate_rmse_m, *reports[1].ate_rmse_m));
  EXPECT_LT(joint_ate, 0.0036);  // measured 0.0018 m (alone 0.0008 and 0.0023)

  const Vocabulary vocabulary = Vocabulary::load(default_vocabulary_path());
  AtlasStore store = AtlasStore::open(db, vocabulary.hash());
  EXPECT_EQ(store.load_sessions().size(), 2u);
  for (const auto& r : reports) EXPECT_EQ(store.load_trajectory(*r.session).size(), r.trajectory.size());
  Atlas atlas;
  EXPECT_EQ(store.load_atlas(atlas, &vocabulary).maps, 1u);
}

// Two 8-s clips whose flights cross (MH_01 from 46 s, MH_02 from 38 s), each
// mapped with a rule on and off (`run(on, clips, name)`, an atlas per name in a
// folder of the test's) and the first alone with it on; every run must end
// with an ATE.
struct RulesOverTwoRecordings {
  std::vector<DatasetRunReport> with, without, alone;
};
using RecordingsRun = std::function<std::vector<DatasetRunReport>(
    bool on, const std::vector<std::filesystem::path>& clips, const std::filesystem::path& atlas)>;
void run_over_two_recordings(const std::string& name, const RecordingsRun& run, RulesOverTwoRecordings& out) {
  const auto a = test::simulated_clip("MH_01", 46.0, 8.0);
  test::ClipCleanup cleanup_a{a};
  const auto b = test::simulated_clip("MH_02", 38.0, 8.0);
  test::ClipCleanup cleanup_b{b};
  const auto dir =
      std::filesystem::temp_directory_path() / ("orbatlas_test_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  test::ClipCleanup cleanup_dir{dir};
  out.with = run(true, {a, b}, dir / "with.db");
  out.without = run(false, {a, b}, dir / "without.db");
  out.alone = run(true, {a}, dir / "alone.db");
  ASSERT_EQ(out.with.size(), 2u);
  ASSERT_EQ(out.without.size(), 2u);
  ASSERT_EQ(out.alone.size(), 1u);
  for (const auto* reports : {&out.with, &out.without, &out.alone})
    for (const auto& r : *reports) {
      EXPECT_TRUE(r.failed.empty()) << r.failed;
      ASSERT_TRUE(r.ate_rmse_m.has_value());
    }
}

// Two recordings mapping one map at once re-observe each other's points, which
// closes no loop: the map gets a global BA each time it has grown by half since
// its last one (LoopCloserOptions::shared_map_refinement_growth); never with the
// rule off, and never for a map of one session.
TEST(AtlasSessions, AMapSeveralRecordingsMapAtOnceIsAdjustedWholeAsItGrows) {
  const auto shared_map_runs = [](const DatasetRunReport& r) {
    return std::count_if(r.stats.loop.global_adjustments.begin(), r.stats.loop.global_adjustments.end(),
                         [](const GlobalAdjustmentRun& g) { return g.cause == GlobalAdjustmentCause::kSharedMap; });
  };
  RulesOverTwoRecordings runs;
  run_over_two_recordings(
      "shared_ba",
      [](bool on, const std::vector<std::filesystem::path>& clips, const std::filesystem::path& atlas) {
        DatasetRunOptions options = options_for(clips.front(), atlas);
        options.slam.synchronous_mapping = true;
        options.slam.loop.shared_map_refinement_growth = on ? 0.5 : 0.0;
        options.slam.loop.shared_map_refinement_min_keyframes = 8;
        return run_datasets(options, clips);
      },
      runs);
  if (HasFatalFailure()) return;
  const auto& [with, without, alone] = runs;
  EXPECT_GE(shared_map_runs(with[0]), 1);
  EXPECT_EQ(shared_map_runs(without[0]), 0);
  EXPECT_EQ(shared_map_runs(alone[0]), 0);
  std::set<MapId> maps(with[0].trajectory_maps.begin(), with[0].trajectory_maps.end());
  maps.insert(with[1].trajectory_maps.begin(), with[1].trajectory_maps.end());
  EXPECT_EQ(maps.size(), 1u);  // one map, adjusted whole
  for (const auto& r : with)
    EXPECT_LT(*r.ate_rmse_m, 0.0075);  // measured 0.0029-0.0037 m (without the rule the same, on 8-s clips)
}

// A recording that ends in a map another recording mapped too waits, in its
// finish, for a global BA of that map (SlamSystemOptions::shared_map_finish_wait_s,
// LoopCloser::refine_at_stream_end), the server's finish too: one, by the first
// recording to end (the second finds the map adjusted since). None without the
// wait, none for a map of one recording.
TEST(AtlasSessions, ARecordingEndingInASharedMapHasTheMapAdjustedInItsFinish) {
  const auto stream_end_runs = [](const DatasetRunReport& r) {
    std::vector<GlobalAdjustmentRun> runs;
    for (const auto& g : r.stats.loop.global_adjustments)
      if (g.cause == GlobalAdjustmentCause::kStreamEnd) runs.push_back(g);
    return runs;
  };
  RulesOverTwoRecordings runs;
  run_over_two_recordings(
      "end_ba",
      [](bool on, const std::vector<std::filesystem::path>& clips, const std::filesystem::path& atlas) {
        DatasetRunOptions options = options_for(clips.front(), atlas);
        options.slam.synchronous_mapping = true;
        options.slam.loop.shared_map_refinement_growth = 0.0;  // only merges' and the ends' global BAs
        options.slam.loop.shared_map_refinement_min_keyframes = 8;
        options.slam.shared_map_finish_wait_s = on ? 60.0 : 0.0;
        return run_datasets(options, clips);
      },
      runs);
  if (HasFatalFailure()) return;
  const auto& [with, without, alone] = runs;
  const auto ended = stream_end_runs(with[0]);
  std::set<MapId> maps(with[0].trajectory_maps.begin(), with[0].trajectory_maps.end());
  maps.insert(with[1].trajectory_maps.begin(), with[1].trajectory_maps.end());
  ASSERT_EQ(maps.size(), 1u);  // the two recordings' map: merged, shared
  ASSERT_EQ(ended.size(), 1u);
  EXPECT_FALSE(ended[0].interrupted);
  EXPECT_GE(ended[0].keyframes, 8u);
  EXPECT_TRUE(stream_end_runs(without[0]).empty());
  EXPECT_TRUE(stream_end_runs(alone[0]).empty());
  for (const auto& r : with) EXPECT_LT(*r.ate_rmse_m, 0.0075);
}

// In a map another session maps too, a session's keyframe decision counts as
// tracked only the close points its own keyframes observe
// (TrackerOptions::own_close_points): a session flying through the other's
// points makes keyframes of its own there, whose close stereo observations tie
// its path to the map. Alone every point is the session's own: the same run.
TEST(AtlasSessions, ASessionInAnothersMapMakesKeyframesForItsOwnClosePoints) {
  const auto a = test::simulated_clip("MH_01", 46.0, 8.0);
  test::ClipCleanup cleanup_a{a};
  const auto b = test::simulated_clip("MH_02", 38.0, 8.0);
  test::ClipCleanup cleanup_b{b};
  const auto dir = std::filesystem::temp_directory_path() / ("orbatlas_test_own_close_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  test::ClipCleanup cleanup_dir{dir};
  const auto run = [&](bool own, const std::vector<std::filesystem::path>& clips, const std::string& name,
                       int max_local_keyframes = TrackerOptions{}.max_local_keyframes) {
    DatasetRunOptions options = options_for(clips.front(), dir / (name + ".db"));
    options.slam.synchronous_mapping = true;
    options.slam.tracker.own_close_points = own;
    options.slam.tracker.max_local_keyframes = max_local_keyframes;
    return run_datasets(options, clips);
  };
  const auto with = run(true, {a, b}, "with");
  const auto without = run(false, {a, b}, "without");
  const auto alone_with = run(true, {a}, "alone_with");
  const auto alone_without = run(false, {a}, "alone_without");
  ASSERT_EQ(with.size(), 2u);
  ASSERT_EQ(without.size(), 2u);
  for (const auto* reports : {&with, &without, &alone_with, &alone_without})
    for (const auto& r : *reports) {
      EXPECT_TRUE(r.failed.empty()) << r.failed;
      ASSERT_TRUE(r.ate_rmse_m.has_value());
    }
  // MH_02 tracks MH_01's points (measured 6-7 keyframes with the rule, 2-5
  // without, in 14 runs; MH_01 10-11 and 8-11).
  EXPECT_GT(with[1].stats.keyframes_made, without[1].stats.keyframes_made);
  for (const auto& r : with) EXPECT_LT(*r.ate_rmse_m, 0.0075);  // measured 0.0022-0.0041 m (without 0.0023-0.0039)

  ASSERT_EQ(alone_with.size(), 1u);
  ASSERT_EQ(alone_without.size(), 1u);
  const Trajectory& x = alone_with[0].trajectory;
  const Trajectory& y = alone_without[0].trajectory;
  ASSERT_EQ(x.size(), y.size());
  // The same run. Separate `orbatlas run --synchronous` processes give the
  // same trajectory to the last bit with and without the rule (12 runs); runs
  // one after another in this process do not always (poses up to 2.2 mm
  // apart, the same ATE): a rare flip to one other trajectory, 3 runs in about
  // 200 of one run per atlas file, once with checkpoints every 0.2 s; the
  // checkpointer's thread is suspected, not found yet. So the poses are
  // compared at a bound.
  double largest = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    ASSERT_EQ(x[i].t_ns, y[i].t_ns);
    largest = std::max(largest, translation_distance(x[i].pose, y[i].pose));
  }
  EXPECT_NEAR(*alone_with[0].ate_rmse_m, *alone_without[0].ate_rmse_m, 0.0005);
  EXPECT_LT(largest, 0.005);

  // The local map a frame is tracked in: in the shared map MH_02's frames see
  // MH_01's keyframes too. At most max_local_keyframes keyframes, those that
  // observe the frame's points included (the ones sharing most points first).
  const auto local_keyframes = [](const DatasetRunReport& r) { return percentiles(r.stats.local_map_keyframes); };
  const auto local_points = [](const DatasetRunReport& r) { return percentiles(r.stats.local_map_points); };
  for (const auto* reports : {&with, &alone_with})
    for (const auto& r : *reports) {
      EXPECT_GT(local_keyframes(r).count, r.stats.tracked * 9 / 10);  // nearly every frame is tracked in one
      EXPECT_LE(local_keyframes(r).max, 80.0);
      EXPECT_GT(local_points(r).p50, 100.0);
      EXPECT_EQ(r.stats.maps_wait_ms.count(), r.stats.frames);  // every frame's wait for the maps
    }
  EXPECT_GT(local_keyframes(with[1]).max, 8.0);
  const auto capped = run(true, {a, b}, "capped", 8);
  ASSERT_EQ(capped.size(), 2u);
  for (const auto& r : capped) {
    EXPECT_TRUE(r.failed.empty()) << r.failed;
    EXPECT_LE(local_keyframes(r).max, 8.0);
    EXPECT_GT(local_keyframes(r).count, r.stats.tracked * 9 / 10);
    ASSERT_TRUE(r.ate_rmse_m.has_value());
    EXPECT_LT(*r.ate_rmse_m, 0.0075);
  }
}

}  // namespace
}  // namespace orbatlas
