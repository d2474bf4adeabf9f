// The map server end to end on loopback: a streamed clip matches the offline
// run, survives a restart, and its frames localise against the stored map;
// three sessions stream at once; a clip in passes; a stream stopped early;
// an uploaded recording.
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
    const auto s = test::pose_at_time(streamed.trajectory, p.t_ns);
    ASSERT_TRUE(s.has_value()) << p.t_ns;
    worst = std::max(worst, (s->t - p.pose.t).norm());
  }
  EXPECT_LT(worst, 0.015);  // measured 0.0010-0.0079 m over 11 runs (concurrent mapping: the worst frame varies)
  EXPECT_NEAR(*streamed.ate_rmse_m, *offline.ate_rmse_m, 0.01);

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
  const auto visit = test::another_flight();
  test::ClipCleanup visit_cleanup{visit};
  const DatasetFrame f = test::stereo_frames(visit)[30];
  const cv::Mat left = cv::imread(f.left.string(), cv::IMREAD_GRAYSCALE);
  const cv::Mat right = cv::imread(f.right.string(), cv::IMREAD_GRAYSCALE);
  const std::optional<Pose3> expected = test::truth_in_map(visit, f.t_ns, clip, test::stereo_frames(clip).front().t_ns);
  for (const bool pair : {true, false}) {
    const auto reply = client.localize("euroc/stereo", left, pair ? right : cv::Mat());
    ASSERT_TRUE(reply["recognised"].get<bool>()) << reply.dump();
    EXPECT_EQ(reply["map"], maps_after["maps"][0]["id"]);
    const Pose3 T_w_b = pose_from_json(reply["T_w_b"]);
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
  EXPECT_LT(translation_distance(first, third), 0.001);  // measured 0.0002 m (three runs)
  // Each pass is compared with the ground truth of what it replays.
  ASSERT_TRUE(report.ate_rmse_m.has_value());
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
  // The same without a config (the recording's own settings are known only once it is in).
  const auto bad_mode_alone = client.http().Post("/v1/uploads?mode=fly", std::string(10, 'x'), "application/x-tar");
  ASSERT_TRUE(bad_mode_alone);
  EXPECT_EQ(bad_mode_alone->status, 400) << bad_mode_alone->body;
  EXPECT_NE(bad_mode_alone->body.find("map or localize"), std::string::npos) << bad_mode_alone->body;
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

// Two sessions over one part of the hall (MH_01 from 46 s, MH_02 from 38 s):
// each streams into a map of its own; when the second finishes, the server's
// merging worker recognises the shared place and merges its map into the
// first. Both trajectories then come back in one map and fit the ground truth
// under one alignment, also after a restart. A later session over the same place
// starts in that map.

}  // namespace
}  // namespace orbatlas
