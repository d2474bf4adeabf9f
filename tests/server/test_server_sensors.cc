// Every sensor through the server: stereo-inertial, RGB-D, a single camera
// mapping at its own scale and with its IMU in metres, and a single camera
// localising in the stored map.
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
  // The clip's ideal IMU: its links use the settings' white noise, or a little
  // above what the samples show.
  ASSERT_TRUE(slam.contains("imu_white_noise")) << report.finish_status.dump();
  EXPECT_GE(slam["imu_white_noise"]["gyro"].get<double>(), ImuNoise{}.gyro_density);
  EXPECT_LT(slam["imu_white_noise"]["gyro"].get<double>(), 1.18 * ImuNoise{}.gyro_density);
  EXPECT_GE(slam["imu_white_noise"]["acc"].get<double>(), ImuNoise{}.accel_density);
  EXPECT_LT(slam["imu_white_noise"]["acc"].get<double>(), 1.13 * ImuNoise{}.accel_density);
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
  EXPECT_LT(*report.ate_rmse_m, 0.002);  // measured 0.0009 m
  const auto merges = test::wait_for_merges(client);
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
  EXPECT_NEAR(stored_ate, streamed_ate, 1e-4);
  EXPECT_NEAR(scale, 1.0, 0.1);  // metric (measured within 0.056), not the arbitrary scale (x6-8) of its start
}

TEST(ServerEndToEnd, ASingleCameraSessionLocalisesInTheStoredMap) {
  const auto clip = test::simulated_clip("MH_01", 40.0, 4.0);
  test::ClipCleanup cleanup{clip};
  const auto visit = test::another_flight();  // what the single camera sees: not the images that built the map
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
  const nlohmann::json status = client.get_json("/v1/sessions/" + std::to_string(report.session));
  EXPECT_EQ(status["sensor"], "mono");
  EXPECT_EQ(status["state"], "finished");
  const nlohmann::json maps_after = client.get_json("/v1/maps");
  ASSERT_EQ(maps_after["maps"].size(), 1u);
  EXPECT_EQ(maps_after["maps"][0]["keyframes"], maps_before["maps"][0]["keyframes"]);
  EXPECT_EQ(maps_after["maps"][0]["map_points"], maps_before["maps"][0]["map_points"]);
}

}  // namespace
}  // namespace orbatlas
