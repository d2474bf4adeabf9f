// The map server end to end on loopback: a streamed clip matches the offline
// run, survives a restart, and its frames localise against the stored map;
// three sessions stream at once.
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
#include "tests/support/server_test_fixture.h"
#include "tests/support/server_test_reply.h"
#include "tests/support/slam_test_clip.h"

namespace orbatlas {
namespace {

// Another flight through the place MH_01 maps at 40-50 s: MH_02 at 41-44 s
// passes 0.3 to 0.9 m from it, looking the same way within 25 deg; no pose
// that built the map is re-rendered.
std::filesystem::path another_flight() { return test::simulated_clip("MH_02", 41.0, 3.0); }

// The ground truth of `dataset` at t_ns in the frame of a map whose origin is
// the body at `origin_t_ns` of `origin_dataset` (all Machine Hall sequences
// share one world frame).
Pose3 truth_in_map(const std::filesystem::path& dataset, TimestampNs t_ns, const std::filesystem::path& origin_dataset,
                   TimestampNs origin_t_ns) {
  const auto at = [](const std::filesystem::path& d, TimestampNs t) {
    Trajectory gt;
    for (const auto& s : test::stereo_dataset(d).ground_truth) gt.push_back({s.t_ns, s.T_w_b});
    const auto pose = pose_at(gt, t, 50'000'000);
    EXPECT_TRUE(pose.has_value()) << d << " has no ground truth at " << t;
    return pose.value_or(Pose3());
  };
  return at(origin_dataset, origin_t_ns).inverse() * at(dataset, t_ns);
}

nlohmann::json wait_for_merges(ServerClient& client) {
  for (int i = 0; i < 1200; ++i) {
    const auto merges = client.get_json("/v1/merges");
    if (merges["pending"].get<std::size_t>() == 0) return merges;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return client.get_json("/v1/merges");
}

// A single camera's trajectory (the left camera's poses) against the
// dataset's ground truth.
EvalResult left_camera_eval(const EurocDataset& dataset, const Trajectory& trajectory, AlignMode align) {
  EvalOptions eval;
  eval.align = align;
  eval.estimate_T_b_x = dataset.cameras[0].calibration.T_b_c;
  return evaluate_trajectory(trajectory, from_ground_truth_states(dataset.ground_truth), eval);
}

std::optional<Pose3> pose_at_time(const Trajectory& t, TimestampNs t_ns) {
  for (const auto& p : t)
    if (p.t_ns == t_ns) return p.pose;
  return std::nullopt;
}

TEST(ServerEndToEnd, StreamedClipMatchesOfflineSurvivesRestartAndLocalises) {
  const auto clip = test::simulated_clip("MH_01", 40.0, 10.0);
  test::ClipCleanup cleanup{clip};
  DatasetRunOptions offline_options;
  offline_options.settings = shipped_config_dir() / "euroc" / "stereo.yaml";
  offline_options.dataset = clip;
  offline_options.show_progress = false;
  const DatasetRunReport offline = run_dataset(offline_options);
  ASSERT_TRUE(offline.ate_rmse_m.has_value());

  test::TempDbPath db("e2e");
  StreamReport streamed;
  nlohmann::json maps_before, status_before;
  {
    test::TestServer server(test::server_options(db.path));
    ServerClient client(server.url());
    streamed = stream_dataset(client, test::stream_options(clip));
    maps_before = client.get_json("/v1/maps");
    status_before = client.get_json("/v1/sessions/" + std::to_string(streamed.session));
    EXPECT_EQ(status_before["state"], "finished");
    EXPECT_EQ(status_before["frames"].get<std::size_t>(), 201u);
    // Where each frame's time went, per session and in /metrics: the whole
    // request, the images' decoding, the wait for the maps inside tracking.
    for (const char* key : {"request_ms", "decode_ms", "maps_wait_ms", "tracking_ms"}) {
      ASSERT_TRUE(status_before.contains(key)) << key;
      EXPECT_EQ(status_before[key]["count"], 201u) << key;
      EXPECT_LE(status_before[key]["p95"].get<double>(), status_before[key]["p99"].get<double>()) << key;
      EXPECT_LE(status_before[key]["p99"].get<double>(), status_before[key]["max"].get<double>()) << key;
    }
    EXPECT_GE(status_before["request_ms"]["p50"].get<double>(), status_before["tracking_ms"]["p50"].get<double>());
    EXPECT_LE(status_before["maps_wait_ms"]["p50"].get<double>(), status_before["tracking_ms"]["p50"].get<double>());
    EXPECT_NE(client.get_text("/metrics").find("orbatlas_frame_request_seconds_count 201"), std::string::npos);
    // The live poses: one per tracked frame, as replied; scored beside the final trajectory.
    EXPECT_EQ(streamed.live_trajectory.size(), 201u);
    EXPECT_DOUBLE_EQ(streamed.live_fraction(), 1.0);
    ASSERT_TRUE(streamed.live_ate_rmse_m.has_value());
    std::printf("streamed clip: live ATE %.4f m, final %.4f m; request p50 %.1f / p99 %.1f ms, decode p50 %.2f ms\n",
                *streamed.live_ate_rmse_m, streamed.ate_rmse_m.value_or(0.0),
                status_before["request_ms"]["p50"].get<double>(), status_before["request_ms"]["p99"].get<double>(),
                status_before["decode_ms"]["p50"].get<double>());
    EXPECT_LT(*streamed.live_ate_rmse_m, 0.004);  // measured 0.0019 m (the final 0.0019 m)
  }
  EXPECT_EQ(streamed.frames, 201u);
  EXPECT_EQ(streamed.rejected, 0u);
  EXPECT_EQ(streamed.tracked, streamed.frames);
  // One timing per frame answered (--frame-log), in order, each as the summaries count it.
  ASSERT_EQ(streamed.frame_timings.size(), 201u);
  std::size_t keyframes = 0;
  for (std::size_t i = 0; i < streamed.frame_timings.size(); ++i) {
    const StreamReport::FrameTiming& f = streamed.frame_timings[i];
    EXPECT_DOUBLE_EQ(f.round_trip_ms, streamed.round_trip_ms[i]);
    EXPECT_DOUBLE_EQ(f.tracking_ms, streamed.tracking_ms[i]);
    EXPECT_LE(f.tracking_ms, f.round_trip_ms);
    EXPECT_FALSE(f.skipped || f.late);  // not paced: nothing is due
    if (i > 0) {
      EXPECT_GT(f.t_ns, streamed.frame_timings[i - 1].t_ns);
      EXPECT_GE(f.sent_unix_us, streamed.frame_timings[i - 1].sent_unix_us);
    }
    keyframes += f.keyframe ? 1 : 0;
  }
  EXPECT_EQ(keyframes, streamed.keyframes);
  // The finish request stores the session's last frames (a checkpoint) before it replies.
  EXPECT_GT(streamed.finish_ms, 0.0);
  EXPECT_LT(streamed.finish_ms, 30000.0);
  ASSERT_EQ(streamed.trajectory.size(), offline.trajectory.size());
  ASSERT_TRUE(streamed.ate_rmse_m.has_value());
  EXPECT_LT(*streamed.ate_rmse_m, 0.004);  // measured 0.0020 m
  // Local mapping runs concurrently in both, so they are not bit-identical;
  // both start at the identity and must agree to within a centimetre or two.
  double worst = 0.0;
  for (const auto& p : offline.trajectory) {
    const auto s = pose_at_time(streamed.trajectory, p.t_ns);
    ASSERT_TRUE(s.has_value()) << p.t_ns;
    worst = std::max(worst, (s->t - p.pose.t).norm());
  }
  EXPECT_LT(worst, 0.015);  // measured 0.0010-0.0079 m over 11 runs (concurrent mapping: the worst frame varies)
  EXPECT_NEAR(*streamed.ate_rmse_m, *offline.ate_rmse_m, 0.01);
  std::printf(
      "offline ATE %.4f m, streamed ATE %.4f m, largest position difference %.4f m, %.1f frames/s, "
      "tracking p50 %.1f ms, server p50 %.1f ms, round trip p50 %.1f ms\n",
      *offline.ate_rmse_m, *streamed.ate_rmse_m, worst, streamed.fps(), percentiles(streamed.tracking_ms).p50,
      percentiles(streamed.server_ms).p50, percentiles(streamed.round_trip_ms).p50);

  // Restart on the same database: the map and the session are still there.
  test::TestServer server(test::server_options(db.path));
  ServerClient client(server.url());
  const auto maps_after = client.get_json("/v1/maps");
  ASSERT_EQ(maps_after["maps"].size(), 1u);
  EXPECT_EQ(maps_after["maps"][0]["keyframes"], maps_before["maps"][0]["keyframes"]);
  EXPECT_EQ(maps_after["maps"][0]["map_points"], maps_before["maps"][0]["map_points"]);
  const auto session = client.get_json("/v1/sessions/" + std::to_string(streamed.session));
  EXPECT_EQ(session["state"], "stored");
  // It keeps what it had: counts, mode, config (before: frames became the
  // stored trajectory's size, keyframes 0, mode and config gone).
  for (const char* key : {"frames", "tracked", "keyframes", "rejected_frames", "skipped_frames", "imu_samples", "mode",
                          "config", "name", "sensor"})
    EXPECT_EQ(session[key], status_before[key]) << key << ": " << session.dump();
  EXPECT_GT(session["keyframes"].get<std::size_t>(), 0u);
  EXPECT_FALSE(session.contains("ended_by")) << "the client finished it";
  const std::string tum = client.trajectory_tum(streamed.session);
  // The frame count, the header, "# map"; every stored frame resolves.
  EXPECT_EQ(std::count(tum.begin(), tum.end(), '\n'), static_cast<long>(streamed.trajectory.size()) + 3);
  EXPECT_NE(tum.find("# " + std::to_string(streamed.trajectory.size()) + " frames tracked, " +
                     std::to_string(streamed.trajectory.size()) + " below\n"),
            std::string::npos)
      << tum.substr(0, 200);

  // A frame of another flight through the place localises against the stored
  // map, as a pair and as a single image, where the ground truth puts it in the
  // map's frame (the map starts at the clip's first frame).
  const auto visit = another_flight();
  test::ClipCleanup visit_cleanup{visit};
  const DatasetFrame f = test::stereo_frames(visit)[30];
  const cv::Mat left = cv::imread(f.left.string(), cv::IMREAD_GRAYSCALE);
  const cv::Mat right = cv::imread(f.right.string(), cv::IMREAD_GRAYSCALE);
  const std::optional<Pose3> expected = truth_in_map(visit, f.t_ns, clip, test::stereo_frames(clip).front().t_ns);
  for (const bool pair : {true, false}) {
    const auto reply = client.localize("euroc/stereo", left, pair ? right : cv::Mat());
    ASSERT_TRUE(reply["recognised"].get<bool>()) << reply.dump();
    EXPECT_EQ(reply["map"], maps_after["maps"][0]["id"]);
    const Pose3 T_w_b = pose_from_json(reply["T_w_b"]);
    std::printf("another flight's frame localised as a %s: %.4f m / %.3f deg from the ground truth\n",
                pair ? "pair" : "single image", (T_w_b.t - expected->t).norm(),
                rotation_distance(T_w_b, *expected) * 180.0 / M_PI);
    // Measured 3-4 mm and 0.03 deg on a quiet machine; 13 mm and 0.17 deg once
    // under ctest -j2, where the streamed map itself came out 7.9 mm from the
    // offline one (its concurrent mapping saw other keyframes): the bound
    // covers the map's own error under load.
    EXPECT_LT((T_w_b.t - expected->t).norm(), 0.025) << (pair ? "stereo pair" : "single image");
    EXPECT_LT(rotation_distance(T_w_b, *expected) * 180.0 / M_PI, 0.35);
    EXPECT_GE(reply["inliers"].get<int>(), 50);
  }
  // An image of nothing the atlas holds is "not recognised", not an error.
  const cv::Mat blank(left.rows, left.cols, CV_8UC1, cv::Scalar(128));
  const auto none = client.localize("euroc/stereo", blank);
  EXPECT_FALSE(none["recognised"].get<bool>());
  EXPECT_TRUE(none.contains("reason"));
}

// A stereo-inertial session over HTTP: orbatlas stream sends the
// recording's IMU before each frame, the session links its keyframes by it,
// and the finished session reports its map's inertial initialisation. A plain
// stereo session of the same cameras streamed first: the server's mapping of
// that rig then had visual options; the inertial session maps apart (its own
// mapping, which initialises the IMU, and its own map).
TEST(ServerEndToEnd, AStereoInertialStreamInitialisesItsMap) {
  const auto clip = test::simulated_clip("MH_01", 40.0, 6.0);
  test::ClipCleanup cleanup{clip};
  test::TempDbPath db("inertial");
  test::TestServer server(test::server_options(db.path));
  ServerClient client(server.url());
  StreamOptions plain = test::stream_options(clip);
  plain.duration_s = 2.0;
  plain.preload = true;  // the pairs read back from the in-memory file (PreloadedPairs) are the clip's
  const StreamReport visual = stream_dataset(client, plain);
  ASSERT_EQ(visual.tracked, visual.frames);
  EXPECT_EQ(visual.frames, 40u);  // 2 s at 20 Hz
  StreamOptions o = test::stream_options(clip);
  o.config = "euroc/stereo_inertial";
  const StreamReport report = stream_dataset(client, o);
  EXPECT_EQ(report.tracked, report.frames);
  // The maps the frames were tracked in, as replied while streaming (the
  // merging worker may join the two maps once both sessions have finished).
  ASSERT_FALSE(report.reply_maps.empty());
  ASSERT_FALSE(visual.reply_maps.empty());
  EXPECT_NE(report.reply_maps.front(), visual.reply_maps.front()) << "the inertial session entered the visual map";
  EXPECT_GT(report.imu_samples, 1000u);  // 200 Hz over 6 s
  const nlohmann::json& slam = report.finish_status.at("slam");
  ASSERT_TRUE(slam.contains("imu_initialized_at_s")) << report.finish_status.dump();
  EXPECT_GE(slam["imu_initialized_at_s"].get<double>(), 2.0);
  EXPECT_LT(slam["imu_initialized_at_s"].get<double>(), 4.0);
  EXPECT_EQ(slam["imu_bias"]["gyro"].size(), 3u);
  // A plain stereo session given the same IMU only counts it.
  ServerClient other(server.url());
  const std::uint64_t id = other.create_session("euroc/stereo");
  EXPECT_EQ(other.post_imu(id, {ImuSample{1, Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, 9.81)}})["accepted"], 1);
  other.finish_session(id);

  // An inertial session whose IMU pauses for 0.9 s takes the samples and
  // says so in its status; a stream back in time is refused whole.
  const std::uint64_t inertial = other.create_session("euroc/stereo_inertial");
  const ImuSample a{1'000'000'000, Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, 9.81)};
  ImuSample b = a;
  b.t_ns += 900'000'000;
  EXPECT_EQ(other.post_imu(inertial, {a, b})["accepted"], 2);
  const std::string path = "/v1/sessions/" + std::to_string(inertial);
  const nlohmann::json status = other.get_json(path);
  ASSERT_TRUE(status.contains("imu_warnings")) << status.dump();
  ASSERT_EQ(status["imu_warnings"].size(), 1u);
  EXPECT_NE(status["imu_warnings"][0].get<std::string>().find("IMU gap of 900 ms"), std::string::npos) << status.dump();
  EXPECT_THROW(other.post_imu(inertial, {a}), ServerError);
  other.finish_session(inertial);
  // The warnings stay in the finished session's status (before: gone with its SLAM objects).
  const nlohmann::json finished = other.get_json(path);
  EXPECT_EQ(finished["state"], "finished");
  ASSERT_TRUE(finished.contains("imu_warnings")) << finished.dump();
  EXPECT_EQ(finished["imu_warnings"], status["imu_warnings"]);
}

// An RGB-D session over HTTP: orbatlas stream sends each colour
// image with its 16-bit depth image (the TUM RGB-D layout of sim --depth), the
// server maps with them, and the merging worker refines the map with the
// camera its keyframes were made with. An RGB-D frame's depth errors are
// refused with a clear error; uploads of RGB-D recordings are not supported yet.
TEST(ServerEndToEnd, AnRgbdStreamMapsAndItsDepthIsChecked) {
  const auto clip = test::simulated_clip("MH_01", 40.0, 4.0, /*depth=*/true);
  test::ClipCleanup cleanup{clip};
  test::TempDbPath db("rgbd");
  test::TestServer server(test::server_options(db.path));
  ServerClient client(server.url());
  StreamOptions o = test::stream_options(clip);
  o.config = "euroc/rgbd";
  const StreamReport report = stream_dataset(client, o);
  EXPECT_EQ(report.finish_status.value("sensor", ""), "rgbd");
  EXPECT_EQ(report.tracked, report.frames);
  EXPECT_EQ(report.frames, 81u);
  ASSERT_TRUE(report.ate_rmse_m.has_value());
  std::printf("RGB-D over HTTP: %zu frames, ATE %.4f m\n", report.frames, *report.ate_rmse_m);
  EXPECT_LT(*report.ate_rmse_m, 0.002);  // measured 0.0009 m
  const auto merges = wait_for_merges(client);
  ASSERT_EQ(merges["refinements"].size(), 1u) << merges.dump();
  EXPECT_FALSE(merges["refinements"][0]["interrupted"].get<bool>());

  // Error paths of an RGB-D session's frames.
  const std::uint64_t id = client.create_session("euroc/rgbd");
  const std::string path = "/v1/sessions/" + std::to_string(id) + "/frames";
  const auto frames = read_tum_rgbd(clip).frames;
  const std::string image = test::png_of(cv::imread(frames[0].rgb.string(), cv::IMREAD_GRAYSCALE));
  const std::string depth = test::png_of(cv::imread(frames[0].depth.string(), cv::IMREAD_UNCHANGED));
  const std::string t = std::to_string(frames[0].t_ns);
  const auto status = [&](httplib::MultipartFormDataItems items) {
    const auto r = client.http().Post(path, items);
    return r ? r->status : -1;
  };
  EXPECT_EQ(status({{"t_ns", t, "", ""}, {"left", image, "l.png", "image/png"}}), 400);  // no depth
  EXPECT_EQ(
      status({{"t_ns", t, "", ""}, {"left", image, "l.png", "image/png"}, {"right", image, "r.png", "image/png"}}),
      400);  // a pair
  EXPECT_EQ(
      status({{"t_ns", t, "", ""}, {"left", image, "l.png", "image/png"}, {"depth", image, "d.png", "image/png"}}),
      422);  // 8-bit depth
  EXPECT_EQ(status({{"t_ns", t, "", ""}, {"left", image, "l.png", "image/png"}, {"depth", "raw", "d.raw", ""}}),
            422);  // not a PNG
  const std::string small = test::png_of(cv::Mat(240, 376, CV_16UC1, cv::Scalar(5000)));
  EXPECT_EQ(
      status({{"t_ns", t, "", ""}, {"left", image, "l.png", "image/png"}, {"depth", small, "d.png", "image/png"}}),
      422);  // another size
  EXPECT_EQ(
      status({{"t_ns", t, "", ""}, {"left", image, "l.png", "image/png"}, {"depth", depth, "d.png", "image/png"}}),
      200);
  // A stereo session is not sent depth; an rgbd sensor needs an rgbd config and the reverse.
  const std::uint64_t stereo = client.create_session("euroc/stereo");
  const auto r = client.http().Post(
      "/v1/sessions/" + std::to_string(stereo) + "/frames",
      httplib::MultipartFormDataItems{
          {"t_ns", t, "", ""}, {"left", image, "l.png", "image/png"}, {"depth", depth, "d.png", "image/png"}});
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 400) << r->body;
  EXPECT_NE(r->body.find("RGB-D"), std::string::npos) << r->body;
  const auto mismatch =
      client.http().Post("/v1/sessions", R"({"config": "euroc/stereo", "sensor": "rgbd"})", "application/json");
  ASSERT_TRUE(mismatch);
  EXPECT_EQ(mismatch->status, 400) << mismatch->body;
  const auto upload =
      client.http().Post("/v1/uploads?config=euroc/rgbd&sensor=stereo", std::string(10, 'x'), "application/x-tar");
  ASSERT_TRUE(upload);
  EXPECT_EQ(upload->status, 400) << upload->body;
  EXPECT_NE(upload->body.find("RGB-D"), std::string::npos) << upload->body;
  client.finish_session(id);
  client.finish_session(stereo);

  // The same recording uploaded: an RGB-D session mapped by the server. Its
  // archive holds both layouts (the simulator writes mav0/ beside rgb.txt);
  // the rgbd config reads the TUM one.
  const std::uint64_t job = client.upload(clip, "euroc/rgbd", "recorded RGB-D");
  const auto done = test::wait_for_job(client, job);
  ASSERT_EQ(done["state"], "done") << done.dump();
  EXPECT_EQ(done["tracked"], done["frames_total"]);
  EXPECT_EQ(done["frames_total"], 81);
  ASSERT_TRUE(done.contains("ate_rmse_m"));
  std::printf("uploaded RGB-D recording: ATE %.4f m\n", done["ate_rmse_m"].get<double>());
  EXPECT_LT(done["ate_rmse_m"].get<double>(), 0.002);
  const auto uploaded = client.get_json("/v1/sessions/" + std::to_string(done["session"].get<std::uint64_t>()));
  EXPECT_EQ(uploaded["sensor"], "rgbd");
}

TEST(ServerEndToEnd, ASingleCameraSessionMapsAtItsOwnScale) {
  const auto clip = test::simulated_clip("MH_01", 50.0, 8.0);  // moving from the start
  test::ClipCleanup cleanup{clip};
  test::TempDbPath db("mono_map");
  std::size_t keyframes = 0;
  {
    test::TestServer server(test::server_options(db.path));
    ServerClient client(server.url());
    StreamOptions o = test::stream_options(clip);
    o.config = "euroc/mono";  // maps by default
    const StreamReport report = stream_dataset(client, o);
    EXPECT_EQ(report.finish_status.value("sensor", ""), "mono");
    EXPECT_EQ(report.finish_status.value("mode", ""), "map");
    EXPECT_EQ(report.frames, 161u);
    EXPECT_GE(report.tracked + 8, report.frames);  // the map starts from two views a few frames apart
    EXPECT_GT(report.keyframes, 5u);
    ASSERT_TRUE(report.ate_rmse_m.has_value());
    EXPECT_TRUE(report.ate_sim3);
    std::printf("single camera mapping over HTTP: %zu of %zu frames tracked, %zu keyframes, ATE %.4f m (Sim3)\n",
                report.tracked, report.frames, report.keyframes, *report.ate_rmse_m);
    EXPECT_LT(*report.ate_rmse_m, 0.013);  // measured 0.0061 m
    const nlohmann::json maps = client.get_json("/v1/maps");
    ASSERT_EQ(maps["maps"].size(), 1u) << maps.dump();
    keyframes = maps["maps"][0]["keyframes"].get<std::size_t>();
    EXPECT_GT(keyframes, 5u);
  }
  // Stored: a restarted server holds the map.
  test::TestServer server(test::server_options(db.path));
  ServerClient client(server.url());
  const nlohmann::json maps = client.get_json("/v1/maps");
  ASSERT_EQ(maps["maps"].size(), 1u) << maps.dump();
  EXPECT_EQ(maps["maps"][0]["keyframes"].get<std::size_t>(), keyframes);

  // The recording uploaded with the mono config: cam0 mapped by the server.
  const std::uint64_t job = client.upload(clip, "euroc/mono", "recorded single camera");
  const auto done = test::wait_for_job(client, job);
  ASSERT_EQ(done["state"], "done") << done.dump();
  EXPECT_EQ(done["frames_total"], 161);
  EXPECT_GE(done["tracked"].get<std::size_t>() + 8, 161u);
  ASSERT_TRUE(done.contains("ate_rmse_m"));
  std::printf("uploaded single-camera recording: ATE %.4f m (Sim3)\n", done["ate_rmse_m"].get<double>());
  EXPECT_LT(done["ate_rmse_m"].get<double>(), 0.018);  // measured 0.0089 m
  const auto uploaded = client.get_json("/v1/sessions/" + std::to_string(done["session"].get<std::uint64_t>()));
  EXPECT_EQ(uploaded["sensor"], "mono");
  EXPECT_EQ(uploaded["mode"], "map");
}

// A single camera with its IMU maps on the server (monocular-inertial SLAM):
// its map starts at its own scale and becomes metric at the inertial
// initialisation, which rescales the frames already checkpointed relative to
// its keyframes too (FrameAnchor units): a restarted server gives the same
// metric trajectory.
TEST(ServerEndToEnd, ASingleCameraWithItsImuMapsInMetres) {
  const auto clip = test::simulated_clip("MH_01", 50.0, 10.0);
  test::ClipCleanup cleanup{clip};
  test::TempDbPath db("mono_inertial_map");
  const EurocDataset dataset = test::stereo_dataset(clip);
  const auto camera_ate = [&](const Trajectory& trajectory) {
    EvalOptions eval;  // SE3: metric
    eval.estimate_T_b_x = dataset.cameras[0].calibration.T_b_c;
    return evaluate_trajectory(trajectory, from_ground_truth_states(dataset.ground_truth), eval).ate.rmse;
  };
  std::uint64_t session = 0;
  double streamed_ate = 0.0;
  {
    test::TestServer server(test::server_options(db.path));
    ServerClient client(server.url());
    StreamOptions o = test::stream_options(clip);
    o.config = "euroc/mono_inertial";  // maps by default
    o.rate = 1.0;                      // at the camera's rate, as a device streams (the mapper keeps up)
    const StreamReport report = stream_dataset(client, o);
    session = report.session;
    EXPECT_EQ(report.finish_status.value("sensor", ""), "mono_inertial");
    EXPECT_EQ(report.finish_status.value("mode", ""), "map");
    EXPECT_GT(report.imu_samples, 1800u);  // 200 Hz over 10 s
    const nlohmann::json& slam = report.finish_status.at("slam");
    ASSERT_TRUE(slam.contains("imu_initialized_at_s")) << report.finish_status.dump();
    EXPECT_LT(slam["imu_initialized_at_s"].get<double>(), 4.0);
    ASSERT_TRUE(report.ate_rmse_m.has_value());
    EXPECT_FALSE(report.ate_sim3);
    streamed_ate = *report.ate_rmse_m;
    std::printf(
        "single camera with IMU over HTTP: %zu of %zu frames tracked, IMU initialised at %.2f s, ATE %.4f m "
        "(SE3)\n",
        report.tracked, report.frames, slam["imu_initialized_at_s"].get<double>(), streamed_ate);
    EXPECT_GE(report.tracked + 8, report.frames);
    // Measured 0.007-0.21 m over seven unpaced runs (alone and under the full
    // suite's load): the server maps asynchronously, and when the inertial
    // initialisation and its refinement run moves the scale (docs/monocular.md).
    // Paced at the camera's rate as here, two runs at once: 0.050 and 0.17 m.
    EXPECT_LT(streamed_ate, 0.3);
  }
  test::TestServer server(test::server_options(db.path));
  ServerClient client(server.url());
  std::vector<MapId> maps;
  const Trajectory stored = parse_tum_trajectory(client.trajectory_tum(session), "stored", &maps);
  const double stored_ate = camera_ate(stored);
  EvalOptions sim3;
  sim3.align = AlignMode::kSim3;
  sim3.estimate_T_b_x = dataset.cameras[0].calibration.T_b_c;
  const double scale =
      evaluate_trajectory(stored, from_ground_truth_states(dataset.ground_truth), sim3).alignment.scale;
  std::printf("after a restart: %zu poses, ATE %.4f m (SE3), Sim3 scale %.4f\n", stored.size(), stored_ate, scale);
  EXPECT_NEAR(stored_ate, streamed_ate, 1e-4);
  EXPECT_NEAR(scale, 1.0, 0.1);  // metric (measured within 0.056), not the arbitrary scale (x6-8) of its start
}

TEST(ServerEndToEnd, ThreeSessionsStreamConcurrently) {
  const std::array<std::filesystem::path, 3> clips = {test::simulated_clip("MH_01", 40.0, 4.0),
                                                      test::simulated_clip("MH_02", 30.0, 4.0),
                                                      test::simulated_clip("MH_03", 30.0, 4.0)};
  const test::ClipCleanup cleanups[] = {{clips[0]}, {clips[1]}, {clips[2]}};
  test::TempDbPath db("three");
  AtlasServiceOptions options = test::server_options(db.path);
  options.merge_maps = false;  // concurrency here; merging has its own test
  test::TestServer server(options);
  std::vector<std::future<StreamReport>> running;
  for (const auto& clip : clips) {
    // The first client reads and decodes its whole clip before streaming.
    running.push_back(std::async(std::launch::async, [&server, clip, preload = running.empty()] {
      ServerClient client(server.url());  // one client (connection) per thread
      StreamOptions o = test::stream_options(clip);
      o.preload = preload;
      return stream_dataset(client, o);
    }));
  }
  std::set<std::uint64_t> sessions, maps;
  for (auto& r : running) {
    const StreamReport report = r.get();
    EXPECT_EQ(report.rejected, 0u);
    EXPECT_EQ(report.tracked, report.frames);
    EXPECT_GE(report.frames, 80u);
    ASSERT_TRUE(report.ate_rmse_m.has_value());
    EXPECT_LT(*report.ate_rmse_m, 0.006);  // measured 0.0008-0.0031 m
    sessions.insert(report.session);
    maps.insert(report.trajectory_maps.begin(), report.trajectory_maps.end());
    std::printf("session %llu: %zu frames, ATE %.4f m, %.1f frames/s\n",
                static_cast<unsigned long long>(report.session), report.frames, *report.ate_rmse_m, report.fps());
  }
  EXPECT_EQ(sessions.size(), 3u);
  // A session whose first frame sees a place another session is mapping joins
  // that map (MH_02 and MH_03 at 30 s may: it depends on which starts first).
  EXPECT_GE(maps.size(), 1u);
  EXPECT_LE(maps.size(), 3u);
  ServerClient client(server.url());
  EXPECT_EQ(client.get_json("/v1/maps")["maps"].size(), maps.size());
  const std::string metrics = client.get_text("/metrics");
  EXPECT_NE(metrics.find("orbatlas_sessions_created_total 3"), std::string::npos) << metrics;
  // Errors contained by the workers are reported (none expected here).
  EXPECT_NE(metrics.find("orbatlas_worker_errors_total 0"), std::string::npos) << metrics;
  // The rows the checkpoints wrote: three sessions' frames at least.
  std::smatch rows;
  ASSERT_TRUE(std::regex_search(metrics, rows, std::regex(R"(\norbatlas_checkpoint_rows_total ([0-9.e+]+))")))
      << metrics;
  EXPECT_GT(std::stod(rows[1].str()), 3.0 * 80.0);
  for (const auto session : sessions)
    EXPECT_EQ(client.get_json("/v1/sessions/" + std::to_string(session)).at("worker_errors"), 0u);
  // An SQLite atlas has one server: it is the only replica, without a lease.
  EXPECT_NE(metrics.find("orbatlas_replica_id 1"), std::string::npos) << metrics;
  const nlohmann::json replicas = client.get_json("/v1/replicas");
  EXPECT_EQ(replicas["backend"], "sqlite") << replicas.dump();
  EXPECT_EQ(replicas["self"], 1u) << replicas.dump();
  ASSERT_EQ(replicas["replicas"].size(), 1u) << replicas.dump();
  EXPECT_TRUE(replicas["replicas"][0]["alive"].get<bool>()) << replicas.dump();
  EXPECT_TRUE(replicas["replicas"][0]["self"].get<bool>()) << replicas.dump();
  EXPECT_TRUE(replicas["replicas"][0]["lease_left_s"].is_null()) << replicas.dump();
}

// `orbatlas stream --repeat`: a short clip streamed three times is one long
// session whose passes follow each other in time, every frame tracked (the
// second and third passes revisit the map the first made).
TEST(ServerEndToEnd, AClipStreamedThreeTimesIsOneSessionOfThreePasses) {
  const auto clip = test::simulated_clip("MH_01", 40.0, 2.0);
  test::ClipCleanup cleanup{clip};
  test::TempDbPath db("repeat");
  AtlasServiceOptions options = test::server_options(db.path);
  options.merge_maps = false;
  test::TestServer server(options);
  ServerClient client(server.url());
  const std::size_t once = test::stereo_dataset(clip).cameras[0].frames.size();
  StreamOptions o = test::stream_options(clip);
  o.repeat = 3;
  const StreamReport report = stream_dataset(client, o);
  EXPECT_EQ(report.frames, 3 * once);
  EXPECT_EQ(report.tracked, report.frames);
  ASSERT_EQ(report.trajectory.size(), report.frames);
  for (std::size_t i = 1; i < report.trajectory.size(); ++i)
    ASSERT_GT(report.trajectory[i].t_ns, report.trajectory[i - 1].t_ns) << "pose " << i;
  // The third pass is where the first was: the same place, 2 s of frames on.
  const Pose3& first = report.trajectory[0].pose;
  const Pose3& third = report.trajectory[2 * once].pose;
  std::printf("three passes: %zu frames, the third pass's first pose %.4f m / %.3f deg from the first's\n",
              report.frames, translation_distance(first, third), rotation_distance(first, third) * 180.0 / M_PI);
  EXPECT_LT(translation_distance(first, third), 0.001);  // measured 0.0002 m (three runs)
  // Each pass is compared with the ground truth of what it replays.
  ASSERT_TRUE(report.ate_rmse_m.has_value());
  std::printf("three passes: ATE %.4f m over %zu poses\n", *report.ate_rmse_m, report.ate_poses);
  EXPECT_EQ(report.ate_poses, report.frames);
  EXPECT_LT(*report.ate_rmse_m, 0.002);  // measured 0.0006 m
  StreamOptions imu = test::stream_options(clip);
  imu.config = "euroc/stereo_inertial";
  imu.repeat = 2;
  EXPECT_THROW(stream_dataset(client, imu), Error);
}

// StreamOptions::stop ends a stream before its clip does: the frames sent so
// far, and the session finished as at the clip's end.
TEST(ServerEndToEnd, AStreamStoppedEarlyFinishesItsSession) {
  const auto clip = test::simulated_clip("MH_01", 40.0, 2.0);
  test::ClipCleanup cleanup{clip};
  test::TempDbPath db("stopped");
  AtlasServiceOptions options = test::server_options(db.path);
  options.merge_maps = false;
  test::TestServer server(options);
  ServerClient client(server.url());
  StreamOptions o = test::stream_options(clip);
  std::size_t asked = 0;
  o.stop = [&] { return ++asked > 10; };
  const StreamReport report = stream_dataset(client, o);
  EXPECT_EQ(asked, 11u);
  EXPECT_EQ(report.frames, 10u);
  EXPECT_EQ(report.trajectory.size(), 10u);
  const auto status = client.get_json("/v1/sessions/" + std::to_string(report.session));
  EXPECT_EQ(status.at("state"), "finished") << status.dump();
}

// A single camera streams into a server whose stored map (from a restart)
// covers the place: it localises there, replies carry that map, and the map
// is left as it was.
TEST(ServerEndToEnd, ASingleCameraSessionLocalisesInTheStoredMap) {
  const auto clip = test::simulated_clip("MH_01", 40.0, 4.0);
  test::ClipCleanup cleanup{clip};
  const auto visit = another_flight();  // what the single camera sees: not the images that built the map
  test::ClipCleanup visit_cleanup{visit};
  test::TempDbPath db("mono");
  {
    test::TestServer server(test::server_options(db.path));
    ServerClient client(server.url());
    const StreamReport stereo = stream_dataset(client, test::stream_options(clip));
    ASSERT_EQ(stereo.tracked, stereo.frames);
  }
  test::TestServer server(test::server_options(db.path));
  ServerClient client(server.url());
  const nlohmann::json maps_before = client.get_json("/v1/maps");
  ASSERT_EQ(maps_before["maps"].size(), 1u);
  const std::uint64_t stored_map = maps_before["maps"][0]["id"];

  // Frame by frame: one image is a frame; a pair is refused (422), the session goes on.
  const auto frames = test::stereo_frames(visit);
  const nlohmann::json started = client.start_session("euroc/mono", "handheld", "", "localize");
  const std::uint64_t id = started["id"];
  EXPECT_EQ(started["session"]["sensor"], "mono");
  const cv::Mat left = cv::imread(frames[10].left.string(), cv::IMREAD_GRAYSCALE);
  const cv::Mat right = cv::imread(frames[10].right.string(), cv::IMREAD_GRAYSCALE);
  try {
    client.post_frame(id, frames[10].t_ns, left, right);
    ADD_FAILURE() << "a stereo pair was taken by a single-camera session";
  } catch (const ServerError& e) {
    EXPECT_EQ(e.status(), 422);
  }
  const auto reply = client.post_frame(id, frames[10].t_ns, left, cv::Mat());
  EXPECT_TRUE(reply["tracked"].get<bool>()) << reply.dump();
  EXPECT_EQ(reply["map"], stored_map);
  client.finish_session(id);
  // One image against the stored map with the single camera's config; a pair
  // with it is refused.
  const auto placed = client.localize("euroc/mono", left);
  ASSERT_TRUE(placed["recognised"].get<bool>()) << placed.dump();
  EXPECT_EQ(placed["map"], stored_map);
  EXPECT_LT((pose_from_json(placed["T_w_b"]).t - pose_from_json(reply["T_w_b"]).t).norm(), 0.02);
  try {
    client.localize("euroc/mono", left, right);
    ADD_FAILURE() << "a pair was localised with a single camera's config";
  } catch (const ServerError& e) {
    EXPECT_EQ(e.status(), 422);
  }

  // A whole clip through `orbatlas stream --config euroc/mono`, from a recording
  // of the left camera only.
  std::filesystem::remove_all(visit / "mav0" / "cam1");
  StreamOptions mono = test::stream_options(visit);
  mono.config = "euroc/mono";
  mono.mode = "localize";
  const StreamReport report = stream_dataset(client, mono);
  EXPECT_EQ(report.rejected, 0u);
  EXPECT_GE(report.tracked + 2, report.frames);
  EXPECT_EQ(report.keyframes, 0u);
  for (const auto m : report.reply_maps) EXPECT_EQ(m, stored_map);
  ASSERT_TRUE(report.ate_rmse_m.has_value());
  EXPECT_LT(*report.ate_rmse_m, 0.009);  // measured 0.0041 m
  std::printf("single camera over the API: %zu of %zu frames tracked in map %llu, ATE %.4f m, %.1f frames/s\n",
              report.tracked, report.frames, static_cast<unsigned long long>(stored_map), *report.ate_rmse_m,
              report.fps());
  const nlohmann::json status = client.get_json("/v1/sessions/" + std::to_string(report.session));
  EXPECT_EQ(status["sensor"], "mono");
  EXPECT_EQ(status["state"], "finished");
  const nlohmann::json maps_after = client.get_json("/v1/maps");
  ASSERT_EQ(maps_after["maps"].size(), 1u);
  EXPECT_EQ(maps_after["maps"][0]["keyframes"], maps_before["maps"][0]["keyframes"]);
  EXPECT_EQ(maps_after["maps"][0]["map_points"], maps_before["maps"][0]["map_points"]);
}

TEST(ServerUploads, RecordingBecomesAStoredSessionAndBadArchivesAreRefused) {
  const auto clip = test::simulated_clip("MH_01", 40.0, 3.0);
  test::ClipCleanup cleanup{clip};
  test::TempDbPath db("upload");
  test::TestServer server(test::server_options(db.path));
  ServerClient client(server.url());
  std::uint64_t last_progress = 0, total = 0;
  const std::uint64_t job =
      client.upload(clip, "euroc/stereo", "recorded MH_01", [&](std::uint64_t done, std::uint64_t all) {
        EXPECT_GE(done, last_progress);
        last_progress = done;
        total = all;
      });
  EXPECT_EQ(last_progress, total);
  const auto status = test::wait_for_job(client, job);
  ASSERT_EQ(status["state"], "done") << status.dump();
  EXPECT_EQ(status["frames_done"], status["frames_total"]);
  EXPECT_EQ(status["tracked"], status["frames_total"]);
  EXPECT_GE(status["frames_total"].get<int>(), 60);
  ASSERT_TRUE(status.contains("ate_rmse_m"));
  std::printf("uploaded recording: %d frames, ATE %.4f m\n", status["frames_total"].get<int>(),
              status["ate_rmse_m"].get<double>());
  EXPECT_LT(status["ate_rmse_m"].get<double>(), 0.002);  // measured 0.0007 m
  const auto session = client.get_json("/v1/sessions/" + std::to_string(status["session"].get<std::uint64_t>()));
  EXPECT_EQ(session["state"], "finished");
  EXPECT_EQ(session["name"], "recorded MH_01");
  EXPECT_EQ(client.get_json("/v1/maps")["maps"].size(), 1u);
  // The work folder is cleaned up after the job.
  EXPECT_TRUE(std::filesystem::is_empty(db.path.string() + ".work"));

  // Not a tar: refused while it arrives (it is extracted as it comes), with the
  // reason; no job, and the server and the stored map stay.
  const auto not_tar =
      client.http().Post("/v1/uploads?config=euroc/stereo", std::string(3000, 'x'), "application/x-tar");
  ASSERT_TRUE(not_tar);
  EXPECT_EQ(not_tar->status, 422) << not_tar->body;
  EXPECT_NE(not_tar->body.find("not a tar"), std::string::npos) << not_tar->body;
  EXPECT_TRUE(std::filesystem::is_empty(db.path.string() + ".work")) << "the refused upload left files";
  // Unknown config: refused before the body is taken; empty upload; unknown job.
  const auto bad_config = client.http().Post("/v1/uploads?config=no/such", std::string(10, 'x'), "application/x-tar");
  ASSERT_TRUE(bad_config);
  EXPECT_EQ(bad_config->status, 404);
  // A single camera that would only localise: uploads (mapped) refuse it up front.
  const auto mono =
      client.http().Post("/v1/uploads?config=euroc/mono&mode=localize", std::string(10, 'x'), "application/x-tar");
  ASSERT_TRUE(mono);
  EXPECT_EQ(mono->status, 422);
  EXPECT_NE(mono->body.find("unsupported_sensor"), std::string::npos) << mono->body;
  const auto mono_sensor =
      client.http().Post("/v1/uploads?config=euroc/stereo&sensor=mono", std::string(10, 'x'), "application/x-tar");
  ASSERT_TRUE(mono_sensor);
  EXPECT_EQ(mono_sensor->status, 422) << mono_sensor->body;
  const auto bad_mode =
      client.http().Post("/v1/uploads?config=euroc/stereo&mode=fly", std::string(10, 'x'), "application/x-tar");
  ASSERT_TRUE(bad_mode);
  EXPECT_EQ(bad_mode->status, 400) << bad_mode->body;
  EXPECT_NE(bad_mode->body.find("map or localize"), std::string::npos) << bad_mode->body;
  const auto empty = client.http().Post("/v1/uploads", "", "application/x-tar");
  ASSERT_TRUE(empty);
  EXPECT_EQ(empty->status, 400);
  const auto no_job = client.http().Get("/v1/jobs/77");
  ASSERT_TRUE(no_job);
  EXPECT_EQ(no_job->status, 404);
  EXPECT_EQ(client.get_json("/v1/jobs")["jobs"].size(), 1u);
  EXPECT_EQ(client.get_json("/v1/maps")["maps"].size(), 1u);
  EXPECT_EQ(client.get_json("/healthz")["status"], "ok");
}

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

// Two sessions over one part of the hall (MH_01 from 46 s, MH_02 from 38 s):
// each streams into a map of its own; when the second finishes, the server's
// merging worker recognises the shared place and merges its map into the
// first. Both trajectories then come back in one map and fit the ground truth
// under one alignment, also after a restart. A later session over the same place
// starts in that map.
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
    const auto merges = wait_for_merges(client);
    ASSERT_EQ(merges["merges"].size(), 1u) << merges.dump(2);
    // The first session's map, alone in the atlas when it finished, was refined by a global BA.
    ASSERT_EQ(merges["refinements"].size(), 1u) << merges.dump(2);
    EXPECT_EQ(merges["refinements"][0]["map"], stream_maps[0]);
    EXPECT_GT(merges["refinements"][0]["keyframes"].get<int>(), 0);
    const auto& merge = merges["merges"][0];
    std::printf("merge: %s\n", merge.dump().c_str());
    EXPECT_EQ(merge["source_map"], stream_maps[1]);
    EXPECT_EQ(merge["target_map"], stream_maps[0]);
    EXPECT_GE(merge["matches"].get<int>(), 80);
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
  std::printf("joint ATE of both sessions in the merged map: %.4f m (after restart %.4f m)\n", ate_live, ate_restarted);

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
  std::printf(
      "the clip again, started in the stored map: %zu poses compared, largest difference %.4f m, %zu keyframes "
      "made\n",
      compared, worst, again.keyframes);
  EXPECT_GE(compared, again.trajectory.size() * 9 / 10);
  EXPECT_LT(worst, 0.026);  // measured 0.0131 m
  // The merging worker searched only the keyframes this session made.
  const auto merges = wait_for_merges(client);
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
  const auto merges = wait_for_merges(client);
  ASSERT_EQ(merges["refinements"].size(), 1u) << merges.dump(2);
  ASSERT_EQ(merges["merges"].size(), 1u) << merges.dump(2);
  const auto& merge = merges["merges"][0];
  std::printf("refinement: %s\nmerge: %s\n", merges["refinements"][0].dump().c_str(), merge.dump().c_str());
  EXPECT_EQ(merge["source_map"], stream_maps[1]);
  EXPECT_EQ(merge["target_map"], stream_maps[0]);
  EXPECT_TRUE(merge["four_dof"].get<bool>()) << merge.dump();
  const std::size_t first_chain = merges["refinements"][0]["inertial_edges"].get<std::size_t>();
  EXPECT_GE(first_chain, 10u);  // 8 s, a keyframe at least every 0.5 s
  // Both chains: more than the first session's alone.
  EXPECT_GE(merge["global_ba"]["inertial_edges"].get<std::size_t>(), first_chain + 10) << merge.dump();
  std::set<std::uint64_t> in_maps;
  const double ate = joint_ate(client, sessions, clips, &in_maps);
  std::printf("two stereo-inertial sessions, one map: ATE %.4f m\n", ate);
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
    std::printf(
        "second session: live ATE %.4f m (its poses before the merge in its own map's frame), final %.4f m; "
        "%zu jumps, the merge's %.3f m\n",
        *b.live_ate_rmse_m, *b.ate_rmse_m, b.live_jumps_m.size(), merge_jump);

    const auto merges = wait_for_merges(client);
    ASSERT_EQ(merges["live_merges"].size(), 1u) << merges.dump(2);
    const auto& live = merges["live_merges"][0];
    std::printf("live merge: %s; %zu of %zu frames replied in the first map\n", live.dump().c_str(), frames_after,
                b.reply_maps.size());
    EXPECT_EQ(live["session"], b.session);
    EXPECT_EQ(live["source_map"], b.reply_maps.front());
    EXPECT_EQ(live["target_map"], first_map);
    EXPECT_GE(live["matches"].get<int>(), 80);
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
  std::printf("joint ATE of both sessions after the live merge: %.4f m (after restart %.4f m)\n", ate_live,
              ate_restarted);
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
    return left_camera_eval(dataset, trajectory, align);
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
    const StreamReport b = stream_dataset(client, o);
    session = b.session;
    ASSERT_FALSE(b.reply_maps.empty());
    ASSERT_NE(b.reply_maps.front(), first_map);  // it started on its own
    const auto switched = std::find(b.reply_maps.begin(), b.reply_maps.end(), first_map);
    ASSERT_NE(switched, b.reply_maps.end()) << "the single camera's map was not merged into the stereo one";
    EXPECT_GT(b.reply_maps.end() - switched, 100);
    const auto merges = wait_for_merges(client);
    ASSERT_EQ(merges["live_merges"].size(), 1u) << merges.dump(2);
    EXPECT_EQ(client.get_json("/v1/maps")["maps"].size(), 1u);
    const Trajectory trajectory = parse_tum_trajectory(client.trajectory_tum(session), "mono", nullptr);
    ate_live = camera_eval(trajectory, AlignMode::kSe3).ate.rmse;
    const double scale = camera_eval(trajectory, AlignMode::kSim3).alignment.scale;
    std::printf(
        "left camera merged into the stereo map: %zu of %zu replies after it, ATE %.4f m (SE3), Sim3 scale "
        "%.4f\n",
        static_cast<std::size_t>(b.reply_maps.end() - switched), b.reply_maps.size(), ate_live, scale);
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
    return left_camera_eval(dataset, trajectory, align);
  };
  AtlasServiceOptions options = test::server_options(db.path);
  options.start_in_stored_maps = false;
  options.live_merging = false;
  test::TestServer server(options);
  ServerClient client(server.url());
  const StreamReport a = stream_dataset(client, test::stream_options(clips[0]));
  ASSERT_FALSE(a.reply_maps.empty());
  const std::uint64_t stereo_map = a.reply_maps.back();
  wait_for_merges(client);  // the stereo map's own refinement first
  StreamOptions o = test::stream_options(clips[1]);
  o.sensor = "mono";
  o.mode = "map";
  const StreamReport b = stream_dataset(client, o);
  ASSERT_FALSE(b.reply_maps.empty());
  EXPECT_EQ(std::count(b.reply_maps.begin(), b.reply_maps.end(), stereo_map), 0);  // not merged live
  const auto merges = wait_for_merges(client);
  EXPECT_EQ(merges["live_merges"].size(), 0u) << merges.dump(2);
  ASSERT_EQ(merges["merges"].size(), 1u) << merges.dump(2);
  EXPECT_EQ(merges["merges"][0]["target_map"].get<std::uint64_t>(), stereo_map) << merges.dump(2);
  EXPECT_EQ(client.get_json("/v1/maps")["maps"].size(), 1u);
  const Trajectory trajectory = parse_tum_trajectory(client.trajectory_tum(b.session), "mono", nullptr);
  const double ate = camera_eval(trajectory, AlignMode::kSe3).ate.rmse;
  const double scale = camera_eval(trajectory, AlignMode::kSim3).alignment.scale;
  std::printf("left camera merged by the worker into the stereo map: ATE %.4f m (SE3), Sim3 scale %.4f\n", ate, scale);
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
  const auto merges = wait_for_merges(client);
  EXPECT_TRUE(merges.at("merges").empty()) << merges.dump();
  EXPECT_TRUE(merges.at("live_merges").empty()) << merges.dump();
  EXPECT_EQ(client.get_json("/v1/maps")["maps"].size(), 2u);
}
}  // namespace
}  // namespace orbatlas
