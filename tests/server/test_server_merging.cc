// Maps merged by the server: sessions over one place at their ends and while
// they stream, inertial maps keeping both chains, a left camera's map made
// metric, and a session of another rig kept out.
#include <gtest/gtest.h>

#include <algorithm>

#include <array>
#include <fstream>
#include <future>
#include <regex>
#include <thread>
#include <set>
#include <opencv2/imgcodecs.hpp>

#include "client/api/dataset_streamer.h"
#include "core/common/data_paths.h"
#include "core/eval/evaluate.h"
#include "core/io/tum_rgbd.h"
#include "core/io/tum_trajectory.h"
#include "wire/pose_json.h"
#include "core/pipeline/dataset_runner.h"
#include "core/slam/slam_stats.h"
#include "tests/support/server_scenarios.h"
#include "tests/support/server_test_fixture.h"
#include "tests/support/server_test_reply.h"
#include "tests/support/slam_test_clip.h"

namespace orbatlas {
namespace {

// Both sessions' frames as the server returns them, against both ground truths
// under ONE alignment (the recordings share the ground-truth world frame).
double joint_ate(ServerClient& client, const std::vector<std::uint64_t>& sessions,
                 const std::vector<std::filesystem::path>& clips, std::set<std::uint64_t>* maps) {
  std::vector<Trajectory> estimates, ground_truths;
  for (std::size_t i = 0; i < sessions.size(); ++i) {
    std::vector<std::uint64_t> in_maps;
    estimates.push_back(parse_tum_trajectory(client.trajectory_tum(sessions[i]), "trajectory", &in_maps));
    maps->insert(in_maps.begin(), in_maps.end());
    ground_truths.push_back(from_ground_truth_states(test::stereo_dataset(clips[i]).ground_truth));
  }
  return evaluate_trajectory(join_trajectories(estimates, "estimates"),
                             join_trajectories(ground_truths, "ground truth"))
      .ate.rmse;
}

TEST(ServerMerging, SessionsOverOnePlaceEndInOneMapThatSurvivesARestart) {
  const std::vector<std::filesystem::path> clips = {test::simulated_clip("MH_01", 46.0, 8.0),
                                                    test::simulated_clip("MH_02", 38.0, 8.0)};
  const test::ClipCleanup cleanups[] = {{clips[0]}, {clips[1]}};
  test::TempDbPath db("merge");
  std::vector<std::uint64_t> sessions, stream_maps;
  double ate_live = 0.0;
  {
    AtlasServiceOptions options = test::server_options(db.path);
    options.start_in_stored_maps = false;  // the second session makes a map of its own: the merge joins them
    options.live_merging = false;          // ... when it finishes (the live merge has its own test)
    test::TestServer server(options);
    ServerClient client(server.url());
    for (const auto& clip : clips) {
      const StreamReport report = stream_dataset(client, test::stream_options(clip));
      EXPECT_EQ(report.tracked, report.frames);
      sessions.push_back(report.session);
      // The map the replies named while it streamed: the trajectory, fetched
      // after the session finished, may already be in the merged map (the
      // merge starts when the session finishes and has once won that race).
      ASSERT_FALSE(report.reply_maps.empty());
      stream_maps.push_back(report.reply_maps.front());
    }
    const auto merges = test::wait_for_merges(client);
    ASSERT_EQ(merges["merges"].size(), 1u) << merges.dump(2);
    // The first session's map, alone in the atlas when it finished, was refined by a global BA.
    ASSERT_EQ(merges["refinements"].size(), 1u) << merges.dump(2);
    EXPECT_EQ(merges["refinements"][0]["map"], stream_maps[0]);
    EXPECT_GT(merges["refinements"][0]["keyframes"].get<int>(), 0);
    const auto& merge = merges["merges"][0];
    EXPECT_EQ(merge["source_map"], stream_maps[1]);
    EXPECT_EQ(merge["target_map"], stream_maps[0]);
    EXPECT_GE(merge["matches"].get<int>(), 80) << merge.dump();
    EXPECT_FALSE(merge["global_ba"]["interrupted"].get<bool>());
    const auto maps = client.get_json("/v1/maps")["maps"];
    ASSERT_EQ(maps.size(), 1u);
    EXPECT_EQ(maps[0]["id"], stream_maps[0]);
    std::set<std::uint64_t> in_maps;
    ate_live = joint_ate(client, sessions, clips, &in_maps);
    EXPECT_EQ(in_maps, std::set<std::uint64_t>{stream_maps[0]});
    EXPECT_LT(ate_live, 0.008);  // measured 0.0040 m
    // The second session's status names the map it is in now.
    EXPECT_EQ(client.get_json("/v1/sessions/" + std::to_string(sessions[1]))["map"], stream_maps[0]);
    EXPECT_NE(client.get_text("/metrics").find("orbatlas_map_merges_total 1"), std::string::npos);
  }
  // Restart: one map, both trajectories in it, the same fit.
  test::TestServer server(test::server_options(db.path));
  ServerClient client(server.url());
  EXPECT_EQ(client.get_json("/v1/maps")["maps"].size(), 1u);
  std::set<std::uint64_t> in_maps;
  const double ate_restarted = joint_ate(client, sessions, clips, &in_maps);
  EXPECT_EQ(in_maps, std::set<std::uint64_t>{stream_maps[0]});
  EXPECT_NEAR(ate_restarted, ate_live, 1e-4);

  // A new session over a known place starts in the stored map (its frame, no
  // map of its own): the second clip streamed again lands where it was.
  const std::size_t searched_before = client.get_json("/v1/merges")["keyframes_searched"].get<std::size_t>();
  const StreamReport again = stream_dataset(client, test::stream_options(clips[1]));
  EXPECT_EQ(again.tracked, again.frames);
  EXPECT_EQ(std::set<std::uint64_t>(again.trajectory_maps.begin(), again.trajectory_maps.end()),
            std::set<std::uint64_t>{stream_maps[0]});
  EXPECT_EQ(client.get_json("/v1/maps")["maps"].size(), 1u);
  std::vector<std::uint64_t> unused;
  const Trajectory before = parse_tum_trajectory(client.trajectory_tum(sessions[1]), "session 2", &unused);
  double worst = 0.0;
  std::size_t compared = 0;
  for (std::size_t i = 0, j = 0; i < again.trajectory.size(); ++i) {
    while (j < before.size() && before[j].t_ns < again.trajectory[i].t_ns) ++j;
    if (j == before.size() || before[j].t_ns != again.trajectory[i].t_ns) continue;
    worst = std::max(worst, (before[j].pose.t - again.trajectory[i].pose.t).norm());
    ++compared;
  }
  EXPECT_GE(compared, again.trajectory.size() * 9 / 10);
  EXPECT_LT(worst, 0.026);  // measured 0.0131 m
  // The merging worker searched only the keyframes this session made.
  const auto merges = test::wait_for_merges(client);
  EXPECT_LE(merges["keyframes_searched"].get<std::size_t>(), searched_before + again.keyframes);
  // Map 0 is refined again when this session extended it (a session that only
  // tracked in it, making no keyframe, leaves it as it was).
  EXPECT_EQ(merges["refinements"].size(), again.keyframes > 0 ? 1u : 0u) << again.keyframes << " keyframes";
  EXPECT_EQ(client.get_json("/v1/maps")["maps"].size(), 1u);
}

// The same two places flown by two stereo-inertial sessions: both
// maps are gravity aligned, so the merge turns the second about the vertical
// only, and the merging worker's global BAs keep the IMU terms: the first map's
// refinement its session's chain, the merged map's both sessions' chains.
TEST(ServerMerging, TwoStereoInertialSessionsMergeKeepingBothImuChains) {
  const std::vector<std::filesystem::path> clips = {test::simulated_clip("MH_01", 46.0, 8.0),
                                                    test::simulated_clip("MH_02", 38.0, 8.0)};
  const test::ClipCleanup cleanups[] = {{clips[0]}, {clips[1]}};
  test::TempDbPath db("merge_inertial");
  AtlasServiceOptions options = test::server_options(db.path);
  options.start_in_stored_maps = false;
  options.live_merging = false;
  test::TestServer server(options);
  ServerClient client(server.url());
  std::vector<std::uint64_t> sessions, stream_maps;
  for (const auto& clip : clips) {
    StreamOptions o = test::stream_options(clip);
    o.config = "euroc/stereo_inertial";
    const StreamReport report = stream_dataset(client, o);
    EXPECT_EQ(report.tracked, report.frames);
    ASSERT_TRUE(report.finish_status.at("slam").contains("imu_initialized_at_s")) << report.finish_status.dump();
    sessions.push_back(report.session);
    ASSERT_FALSE(report.reply_maps.empty());
    stream_maps.push_back(report.reply_maps.front());  // as replied while streaming (the merge may follow at once)
  }
  const auto merges = test::wait_for_merges(client);
  ASSERT_EQ(merges["refinements"].size(), 1u) << merges.dump(2);
  ASSERT_EQ(merges["merges"].size(), 1u) << merges.dump(2);
  const auto& merge = merges["merges"][0];
  EXPECT_EQ(merge["source_map"], stream_maps[1]);
  EXPECT_EQ(merge["target_map"], stream_maps[0]);
  EXPECT_TRUE(merge["four_dof"].get<bool>()) << merge.dump();
  const std::size_t first_chain = merges["refinements"][0]["inertial_edges"].get<std::size_t>();
  EXPECT_GE(first_chain, 10u);  // 8 s, a keyframe at least every 0.5 s
  // Both chains: more than the first session's alone.
  EXPECT_GE(merge["global_ba"]["inertial_edges"].get<std::size_t>(), first_chain + 10) << merge.dump();
  std::set<std::uint64_t> in_maps;
  const double ate = joint_ate(client, sessions, clips, &in_maps);
  EXPECT_EQ(in_maps, std::set<std::uint64_t>{stream_maps[0]});
  EXPECT_LT(ate, 0.004);  // measured 0.0019 m
}

// The same two sessions with live merging: the second session's map is merged
// into the first one's WHILE it streams; the replies switch to the first map
// and stay there, the merge is listed, the worker has nothing left to merge
// when the session finishes, and the result is stored (a restart sees it).
TEST(ServerMerging, ASessionsMapIsMergedWhileItStreams) {
  const std::vector<std::filesystem::path> clips = {test::simulated_clip("MH_01", 46.0, 8.0),
                                                    test::simulated_clip("MH_02", 38.0, 8.0)};
  const test::ClipCleanup cleanups[] = {{clips[0]}, {clips[1]}};
  test::TempDbPath db("live_merge");
  std::vector<std::uint64_t> sessions;
  std::uint64_t first_map = 0;
  double ate_live = 0.0;
  {
    AtlasServiceOptions options = test::server_options(db.path);
    options.start_in_stored_maps = false;  // the second session starts apart
    test::TestServer server(options);
    ServerClient client(server.url());
    const StreamReport a = stream_dataset(client, test::stream_options(clips[0]));
    ASSERT_FALSE(a.reply_maps.empty());
    first_map = a.reply_maps.back();
    const StreamReport b = stream_dataset(client, test::stream_options(clips[1]));
    sessions = {a.session, b.session};
    EXPECT_EQ(b.tracked, b.frames);
    ASSERT_EQ(b.reply_maps.size(), b.tracked);
    ASSERT_NE(b.reply_maps.front(), first_map);  // it started on its own
    // The replies switch to the first map once, and stay.
    const auto switched = std::find(b.reply_maps.begin(), b.reply_maps.end(), first_map);
    ASSERT_NE(switched, b.reply_maps.end()) << "the second session's map was not merged while it streamed";
    EXPECT_TRUE(std::all_of(switched, b.reply_maps.end(), [&](std::uint64_t m) { return m == first_map; }));
    const auto frames_after = static_cast<std::size_t>(b.reply_maps.end() - switched);
    EXPECT_GT(frames_after, 20u);
    // The live poses are the replies' own, one per tracked frame, with the map
    // each reply named; the merge moved the device's pose into the first map's
    // frame: a jump at the first frame after it, counted by the server.
    ASSERT_EQ(b.live_trajectory.size(), b.tracked);
    EXPECT_EQ(b.live_maps, b.reply_maps);
    ASSERT_FALSE(b.live_jumps_m.empty());
    const double merge_jump = *std::max_element(b.live_jumps_m.begin(), b.live_jumps_m.end());
    EXPECT_GT(merge_jump, 0.1) << "measured 0.199 m: the merge moved the session into the first map";
    const nlohmann::json status_b = client.get_json("/v1/sessions/" + std::to_string(b.session));
    EXPECT_EQ(status_b["live_jumps_m"]["count"], b.live_jumps_m.size());
    const std::size_t jumps = a.live_jumps_m.size() + b.live_jumps_m.size();
    EXPECT_NE(client.get_text("/metrics").find("orbatlas_live_pose_jump_meters_count " + std::to_string(jumps)),
              std::string::npos);
    ASSERT_TRUE(b.live_ate_rmse_m.has_value());
    ASSERT_TRUE(b.ate_rmse_m.has_value());

    const auto merges = test::wait_for_merges(client);
    ASSERT_EQ(merges["live_merges"].size(), 1u) << merges.dump(2);
    const auto& live = merges["live_merges"][0];
    EXPECT_EQ(live["session"], b.session);
    EXPECT_EQ(live["source_map"], b.reply_maps.front());
    EXPECT_EQ(live["target_map"], first_map);
    EXPECT_GE(live["matches"].get<int>(), 80) << live.dump();
    EXPECT_TRUE(merges["merges"].empty()) << "the worker merged again: " << merges.dump(2);
    EXPECT_EQ(client.get_json("/v1/maps")["maps"].size(), 1u);
    EXPECT_NE(client.get_text("/metrics").find("orbatlas_map_merges_total 1"), std::string::npos);
    std::set<std::uint64_t> in_maps;
    ate_live = joint_ate(client, sessions, clips, &in_maps);
    EXPECT_EQ(in_maps, std::set<std::uint64_t>{first_map});
    EXPECT_LT(ate_live, 0.007);  // measured 0.0031 m
  }
  test::TestServer server(test::server_options(db.path));
  ServerClient client(server.url());
  EXPECT_EQ(client.get_json("/v1/maps")["maps"].size(), 1u);
  std::set<std::uint64_t> in_maps;
  const double ate_restarted = joint_ate(client, sessions, clips, &in_maps);
  EXPECT_EQ(in_maps, std::set<std::uint64_t>{first_map});
  EXPECT_NEAR(ate_restarted, ate_live, 1e-4);
}

// The left camera of the stereo rig streamed alone (sensor mono, mode map)
// maps at its own scale until it recognises the rig's stereo map; the live
// merge, a similarity, makes its map and its frames (those stored before
// included) metric: its trajectory then meets the ground truth with a rigid
// alignment, also from a restarted server.
TEST(ServerMerging, ALeftCameraSessionIsMergedIntoTheStereoMapAndBecomesMetric) {
  const std::vector<std::filesystem::path> clips = {test::simulated_clip("MH_01", 46.0, 8.0),
                                                    test::simulated_clip("MH_02", 38.0, 8.0)};
  const test::ClipCleanup cleanups[] = {{clips[0]}, {clips[1]}};
  test::TempDbPath db("mono_left_merge");
  const EurocDataset dataset = test::stereo_dataset(clips[1]);
  const auto camera_eval = [&](const Trajectory& trajectory, AlignMode align) {
    return test::left_camera_eval(dataset, trajectory, align);
  };
  std::uint64_t session = 0;
  double ate_live = 0.0;
  {
    AtlasServiceOptions options = test::server_options(db.path);
    options.start_in_stored_maps = false;  // the second session starts apart
    test::TestServer server(options);
    ServerClient client(server.url());
    const StreamReport a = stream_dataset(client, test::stream_options(clips[0]));
    ASSERT_FALSE(a.reply_maps.empty());
    const std::uint64_t first_map = a.reply_maps.back();
    StreamOptions o = test::stream_options(clips[1]);
    o.sensor = "mono";
    o.mode = "map";
    // At the camera's rate, as a device streams: unpaced, on a loaded machine
    // (ctest -j2) the clip ran ahead of the merge worker, which merged at frame
    // 68 of 160 instead of 26-28.
    o.rate = 1.0;
    const StreamReport b = stream_dataset(client, o);
    session = b.session;
    ASSERT_FALSE(b.reply_maps.empty());
    ASSERT_NE(b.reply_maps.front(), first_map);  // it started on its own
    const auto switched = std::find(b.reply_maps.begin(), b.reply_maps.end(), first_map);
    ASSERT_NE(switched, b.reply_maps.end()) << "the single camera's map was not merged into the stereo one";
    EXPECT_GT(b.reply_maps.end() - switched, 100);
    const auto merges = test::wait_for_merges(client);
    ASSERT_EQ(merges["live_merges"].size(), 1u) << merges.dump(2);
    EXPECT_EQ(client.get_json("/v1/maps")["maps"].size(), 1u);
    const Trajectory trajectory = parse_tum_trajectory(client.trajectory_tum(session), "mono", nullptr);
    ate_live = camera_eval(trajectory, AlignMode::kSe3).ate.rmse;
    const double scale = camera_eval(trajectory, AlignMode::kSim3).alignment.scale;
    EXPECT_LT(ate_live, 0.02);
    EXPECT_NEAR(scale, 1.0, 0.02);
  }
  test::TestServer server(test::server_options(db.path));
  ServerClient client(server.url());
  const Trajectory stored = parse_tum_trajectory(client.trajectory_tum(session), "stored", nullptr);
  EXPECT_NEAR(camera_eval(stored, AlignMode::kSe3).ate.rmse, ate_live, 1e-4);
}

// The same two sessions with live merging off: the left camera's map, of its
// own scale, is merged by the server's merging worker once its session ends,
// as a similarity, and its frames become metric as with the live merge.
TEST(ServerMerging, TheMergingWorkerMergesALeftCameraMapIntoTheStereoMapAfterItsSessionEnds) {
  const std::vector<std::filesystem::path> clips = {test::simulated_clip("MH_01", 46.0, 8.0),
                                                    test::simulated_clip("MH_02", 38.0, 8.0)};
  const test::ClipCleanup cleanups[] = {{clips[0]}, {clips[1]}};
  test::TempDbPath db("mono_left_worker");
  const EurocDataset dataset = test::stereo_dataset(clips[1]);
  const auto camera_eval = [&](const Trajectory& trajectory, AlignMode align) {
    return test::left_camera_eval(dataset, trajectory, align);
  };
  AtlasServiceOptions options = test::server_options(db.path);
  options.start_in_stored_maps = false;
  options.live_merging = false;
  test::TestServer server(options);
  ServerClient client(server.url());
  const StreamReport a = stream_dataset(client, test::stream_options(clips[0]));
  ASSERT_FALSE(a.reply_maps.empty());
  const std::uint64_t stereo_map = a.reply_maps.back();
  test::wait_for_merges(client);  // the stereo map's own refinement first
  StreamOptions o = test::stream_options(clips[1]);
  o.sensor = "mono";
  o.mode = "map";
  const StreamReport b = stream_dataset(client, o);
  ASSERT_FALSE(b.reply_maps.empty());
  EXPECT_EQ(std::count(b.reply_maps.begin(), b.reply_maps.end(), stereo_map), 0);  // not merged live
  const auto merges = test::wait_for_merges(client);
  EXPECT_EQ(merges["live_merges"].size(), 0u) << merges.dump(2);
  ASSERT_EQ(merges["merges"].size(), 1u) << merges.dump(2);
  EXPECT_EQ(merges["merges"][0]["target_map"].get<std::uint64_t>(), stereo_map) << merges.dump(2);
  EXPECT_EQ(client.get_json("/v1/maps")["maps"].size(), 1u);
  const Trajectory trajectory = parse_tum_trajectory(client.trajectory_tum(b.session), "mono", nullptr);
  const double ate = camera_eval(trajectory, AlignMode::kSe3).ate.rmse;
  const double scale = camera_eval(trajectory, AlignMode::kSim3).alignment.scale;
  // Measured over four runs: ATE 0.0042-0.0061 m, scale 0.9985-0.9993; alone at
  // background nice 10, scale 0.9972-0.9987; once 0.9954 under a loaded
  // `ctest -j2` (the merge then finds its place with the map less refined).
  EXPECT_LT(ate, 0.012);
  EXPECT_NEAR(scale, 1.0, 0.006);
}

// Local mapping adjusts every keyframe of the map it works in with its own
// session's camera, so a stereo session only enters (relocalises into, starts
// in, merges into) stored maps made with its rig: here the same images with a
// calibration 1 px off in fx stay in a map of their own, also after finishing.
TEST(ServerMerging, ASessionOfAnotherRigStaysOutOfStoredMaps) {
  const auto clip = test::simulated_clip("MH_01", 40.0, 4.0);
  test::ClipCleanup cleanup{clip};
  test::TempDbPath db("rig");
  test::TestServer server(test::server_options(db.path));
  ServerClient client(server.url());
  const StreamReport first = stream_dataset(client, test::stream_options(clip));
  ASSERT_EQ(first.tracked, first.frames);
  const std::uint64_t stored_map = first.trajectory_maps.front();

  std::ifstream in(shipped_config_dir() / "euroc" / "stereo.yaml");
  std::string yaml((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string fx = "Camera1.fx: 458.654";
  ASSERT_NE(yaml.find(fx), std::string::npos);
  yaml.replace(yaml.find(fx), fx.size(), "Camera1.fx: 459.654");
  const std::uint64_t id =
      client.post_json("/v1/sessions", {{"name", "other rig"}, {"settings_yaml", yaml}}).at("id").get<std::uint64_t>();
  std::size_t tracked = 0, in_local_map = 0;
  const auto frames = test::stereo_frames(clip);
  for (const auto& f : frames) {
    const auto reply = client.post_frame(id, f.t_ns, cv::imread(f.left.string(), cv::IMREAD_GRAYSCALE),
                                         cv::imread(f.right.string(), cv::IMREAD_GRAYSCALE));
    if (!reply["tracked"].get<bool>()) continue;
    ++tracked;
    // The local map it was tracked in (none for the frame that starts the map).
    const int local_keyframes = reply.at("local_keyframes").get<int>();
    const int local_points = reply.at("local_points").get<int>();
    EXPECT_LE(local_keyframes, 80);
    EXPECT_EQ(local_keyframes > 0, local_points > 0) << reply.dump();
    if (local_points > 0) ++in_local_map;
    EXPECT_GE(reply.at("maps_wait_ms").get<double>(), 0.0);  // in tracking_ms
    EXPECT_LE(reply.at("maps_wait_ms").get<double>(), reply.at("tracking_ms").get<double>());
    EXPECT_NE(reply["map"].get<std::uint64_t>(), stored_map) << "tracked in the other rig's map at " << f.t_ns;
  }
  EXPECT_EQ(tracked, frames.size());
  EXPECT_GE(in_local_map + 1, frames.size());
  client.finish_session(id);
  const auto merges = test::wait_for_merges(client);
  EXPECT_TRUE(merges.at("merges").empty()) << merges.dump();
  EXPECT_TRUE(merges.at("live_merges").empty()) << merges.dump();
  EXPECT_EQ(client.get_json("/v1/maps")["maps"].size(), 2u);
}

}  // namespace
}  // namespace orbatlas
