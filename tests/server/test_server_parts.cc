// The parts AtlasService is a facade over, each on its own: the session
// registry (ids, the live-session limit, stop, idle expiry), the maps' rigs,
// the mappings per rig, the localiser pool's errors and cache, the metrics.
#include <gtest/gtest.h>

#include <chrono>
#include <condition_variable>
#include <fstream>
#include <iterator>
#include <future>
#include <mutex>

#include <prometheus/text_serializer.h>

#include "core/server/localizer_pool.h"
#include "core/server/map_rig_registry.h"
#include "core/server/rig_mappings.h"
#include "core/server/service_error.h"
#include "core/server/service_metrics.h"
#include "core/server/session_registry.h"
#include "core/vocabulary/default_vocabulary.h"
#include "client/api/dataset_streamer.h"
#include "core/camera/camera_factory.h"
#include "core/common/data_paths.h"
#include "tests/support/server_test_fixture.h"
#include "tests/support/sim_test_helpers.h"
#include "tests/support/slam_test_clip.h"

namespace orbatlas {
namespace {

// A live session that tracks nothing: what the registry needs of one.
class IdleSlam final : public SessionSlam {
 public:
  TrackResult process(TimestampNs, const cv::Mat&, const cv::Mat&) override { return {}; }
  void finish() override {}
  std::vector<FrameAnchor> anchors_from(std::size_t) const override { return {}; }
  std::optional<FrameAnchor> last_anchor() const override { return std::nullopt; }
  SlamStats stats() const override { return SlamStats(); }
  std::size_t worker_errors() const override { return errors; }
  std::size_t errors = 0;
};

std::shared_ptr<LiveSession> live_session(SessionId id, std::size_t errors = 0) {
  SessionInfo info;
  info.id = id;
  auto slam = std::make_unique<IdleSlam>();
  slam->errors = errors;
  return std::make_shared<LiveSession>(info, "test", std::move(slam));
}

std::shared_ptr<LiveSession> stored_session(SessionId id) {
  SessionInfo info;
  info.id = id;
  return std::make_shared<LiveSession>(info, std::nullopt, std::vector<FrameAnchor>{});
}

template <class F>
std::string service_error_code(F&& f) {
  try {
    f();
  } catch (const ServiceError& e) {
    return e.code();
  }
  return "";
}

TEST(SessionRegistry, HandsOutIdsUpToTheLiveLimitAndNoneAfterStop) {
  SessionRegistry sessions(2);
  sessions.add_stored(stored_session(7), true);  // an earlier run's: ids continue after it
  EXPECT_FALSE(sessions.add_stored(stored_session(7), true));
  const SessionId a = sessions.reserve_id();
  EXPECT_EQ(a, 8u);
  sessions.add_live(a, live_session(a, 2), SessionStart{});
  const SessionId b = sessions.reserve_id();
  SessionStart inertial;
  inertial.rig.inertial = true;
  sessions.add_live(b, live_session(b, 3), inertial);
  EXPECT_EQ(service_error_code([&] { sessions.reserve_id(); }), "too_many_sessions");  // stored ones do not count
  EXPECT_EQ(service_error_code([&] { sessions.get(99); }), "not_found");
  EXPECT_EQ(sessions.counts().live, 2u);
  EXPECT_EQ(sessions.counts().ended, 1u);
  EXPECT_EQ(sessions.counts().worker_errors, 0u);  // read from a session as it processes or finishes
  EXPECT_TRUE(sessions.mapping_rig(b).inertial);
  EXPECT_TRUE(sessions.start_of(b).has_value());
  EXPECT_FALSE(sessions.start_of(7).has_value());  // this run did not start it
  sessions.get(a)->finish("");
  EXPECT_EQ(sessions.active().size(), 1u);
  EXPECT_EQ(sessions.reserve_id(), b + 1);  // a slot is free again
  EXPECT_TRUE(sessions.stop());
  EXPECT_FALSE(sessions.stop());
  EXPECT_TRUE(sessions.stopped());
  EXPECT_EQ(service_error_code([&] { sessions.reserve_id(); }), "shutting_down");
}

TEST(SessionRegistry, FinishesOnlySessionsIdleForTheTimeout) {
  SessionRegistry sessions(4);
  const SessionId quiet = sessions.reserve_id();
  sessions.add_live(quiet, live_session(quiet), SessionStart{});
  std::mutex mutex;
  std::condition_variable finished_cv;
  std::vector<SessionId> finished;
  const auto start = std::chrono::steady_clock::now();
  sessions.expire_idle_sessions(0.2, [&](SessionId id) {
    sessions.get(id)->finish("idle_timeout");
    std::lock_guard lock(mutex);
    finished.push_back(id);
    finished_cv.notify_all();
  });
  // A session added later is expired on its own deadline, not the first one's.
  const SessionId busy = sessions.reserve_id();
  sessions.add_live(busy, live_session(busy), SessionStart{});
  {
    std::unique_lock lock(mutex);
    ASSERT_TRUE(finished_cv.wait_for(lock, std::chrono::seconds(5), [&] { return finished.size() == 2; }));
  }
  const double waited = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(finished.front(), quiet);
  EXPECT_EQ(finished.back(), busy);
  EXPECT_GE(waited, 0.2);
  EXPECT_LT(waited, 2.0);
  EXPECT_EQ(sessions.get(quiet)->state(), SessionState::kFinished);
  EXPECT_TRUE(sessions.stop());  // joins the expiry thread
}

TEST(MapRigRegistry, AMapKeepsItsFirstRigAndMergesGoFromASingleCameraToItsStereoRig) {
  const CameraCalibration left = test::euroc_cam0();
  CameraCalibration right = left;
  right.T_b_c.t.x() += 0.11;
  const MapRig stereo{{left, right}, false, false};
  const MapRig mono{{left}, false, true};
  MapRigRegistry rigs;
  rigs.record(1, stereo);
  rigs.record(1, mono);  // kept: the first
  rigs.record(2, mono);
  rigs.record(3, stereo);
  ASSERT_TRUE(rigs.rig_of(1).has_value());
  EXPECT_FALSE(rigs.rig_of(1)->monocular);
  EXPECT_TRUE(rigs.may_merge(3, 1));
  EXPECT_FALSE(rigs.may_merge(1, 2));  // a stereo map does not go into a single camera's
  EXPECT_FALSE(rigs.may_merge(2, 1));  // a single camera's rig is not the stereo rig's cameras
  EXPECT_FALSE(rigs.may_merge(1, 4));  // unknown
  EXPECT_TRUE(rigs.cameras_match({left, right}, 1));
  EXPECT_FALSE(rigs.cameras_match({left}, 1));
  EXPECT_TRUE(rigs.may_map(stereo, 3));
  EXPECT_FALSE(rigs.may_map(MapRig{{left, right}, true, false}, 3));  // IMU fused or not: not one mapping
  rigs.forget(3);
  EXPECT_FALSE(rigs.known(3));
  EXPECT_FALSE(rigs.may_merge(3, 1));
}

TEST(RigMappings, OneMappingPerRigMadeOnceAndFinishedOnce) {
  RigMappings mappings(4, 0);
  const MapRig stereo{{test::euroc_cam0()}, false, false};
  const MapRig inertial{{test::euroc_cam0()}, true, false};
  EXPECT_EQ(mappings.find(stereo), nullptr);
  int made = 0;
  Atlas atlas;
  const auto camera = make_camera(test::euroc_cam0());
  MappingWorkersOptions options;
  options.loop_closing = false;
  const auto make = [&](const std::shared_ptr<SerialWorker>& loop_worker) {
    ++made;
    EXPECT_NE(loop_worker, nullptr);
    return std::make_shared<MappingWorkers>(atlas, FrameCamera{camera.get(), 0.0, ScalePyramid{}}, options);
  };
  const auto first = mappings.for_rig(stereo, make);
  EXPECT_EQ(mappings.for_rig(stereo, make), first);
  EXPECT_NE(mappings.for_rig(inertial, make), first);
  EXPECT_EQ(made, 2);
  EXPECT_EQ(mappings.find(stereo), first);
  EXPECT_EQ(mappings.totals().mappers, 0u);  // no keyframe yet: no map's mapper runs
  mappings.finish();
  mappings.finish();
  EXPECT_EQ(mappings.find(stereo), nullptr);
}

TEST(LocalizerPool, RefusesUnknownMapsAndUnusableSettingsAndKeepsAtMostEightFrontEnds) {
  Atlas atlas;
  const Vocabulary vocabulary = Vocabulary::load(default_vocabulary_path());
  int reads = 0;
  LocalizerPool pool(atlas, vocabulary, [&](const SettingsSource& source) {
    ++reads;
    return load_request_settings(source, shipped_config_dir());
  });
  LocalizeRequest request;
  request.settings.config = "euroc/stereo";
  request.map = 5;
  EXPECT_EQ(service_error_code([&] { pool.localize(request); }), "not_found");
  EXPECT_EQ(service_error_code([&] { pool.image_size(SettingsSource{"no/such", ""}); }), "not_found");
  EXPECT_EQ(service_error_code([&] { pool.image_size(SettingsSource{"", "not: [settings"}); }), "bad_config");
  reads = 0;
  const cv::Size size = pool.image_size(SettingsSource{"euroc/stereo", ""});
  EXPECT_EQ(size, cv::Size(752, 480));
  pool.image_size(SettingsSource{"euroc/stereo", ""});
  EXPECT_EQ(reads, 1);  // kept for the next request
  request.map.reset();
  request.left = cv::Mat(size, CV_8UC1, cv::Scalar(0));
  request.right = request.left.clone();
  EXPECT_FALSE(pool.localize(request).recognised);  // an empty atlas: nothing to recognise
  // Inline settings vary: nine different texts keep the newest eight.
  std::ifstream file(shipped_config_dir() / "euroc" / "stereo.yaml");
  const std::string text((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
  ASSERT_FALSE(text.empty());
  for (int k = 0; k < 9; ++k) pool.image_size(SettingsSource{"", text + "\n# variant " + std::to_string(k) + "\n"});
  EXPECT_EQ(pool.size(), LocalizerPool::kMaxLocalizers);
}

TEST(ServiceMetrics, CountsEventsAndShowsTheStateItIsGiven) {
  ServiceMetrics metrics;
  metrics.session_created();
  metrics.frame_done(20.0, 30.0);
  metrics.frame_done(10.0, 12.0);
  metrics.frame_rejected();
  metrics.localized(true, 40.0);
  metrics.localized(false, 5.0);
  metrics.live_pose_jump(0.02);
  ServiceState now;
  now.live_sessions = 2;
  now.maps = {{4, 120, 2}, {9, 30, 0}};
  now.worker_errors = 3;
  now.merging = ServiceState::Merging{5, 1};
  const std::string text = prometheus::TextSerializer().Serialize(metrics.collect(now));
  for (const char* line :
       {"orbatlas_sessions_created_total 1\n", "orbatlas_frames_total 2\n", "orbatlas_frames_rejected_total 1\n",
        "orbatlas_localize_requests_total 2\n", "orbatlas_localize_recognised_total 1\n",
        "orbatlas_frame_request_seconds_count 2\n", "orbatlas_frame_request_seconds_sum 0.042\n",
        "orbatlas_live_pose_jump_meters_count 1\n", "orbatlas_sessions_live 2\n", "orbatlas_maps 2\n",
        "orbatlas_map_keyframes{map=\"4\"} 120\n", "orbatlas_map_sessions{map=\"4\"} 2\n",
        "orbatlas_worker_errors_total 3\n", "orbatlas_map_merges_total 5\n", "orbatlas_map_merge_pending 1\n"})
    EXPECT_NE(text.find(line), std::string::npos) << line << " not in\n" << text;
  // A total another part keeps never goes down.
  now.worker_errors = 1;
  const std::string again = prometheus::TextSerializer().Serialize(metrics.collect(now));
  EXPECT_NE(again.find("orbatlas_worker_errors_total 3\n"), std::string::npos);
}

// With the background niced (the default), a session that is not real-time
// (no max_lag_s) waits for its local mapping after each keyframe, so that its
// tracking at full speed cannot starve it; a real-time one never waits.
TEST(ServingLiveSessionsFirst, OnlyASessionThatIsNotRealTimeWaitsForItsMapping) {
  const auto clip = test::simulated_clip("MH_01", 40.0, 10.0);
  test::ClipCleanup cleanup{clip};
  test::TempDbPath db("live_first");
  AtlasServiceOptions options = test::server_options(db.path);
  EXPECT_EQ(options.background_nice, 10);
  options.merge_maps = false;
  options.start_in_stored_maps = false;
  test::TestServer server(options);
  ServerClient client(server.url());
  const auto mapping_waits = [&](std::optional<double> max_lag_s) {
    StreamOptions o = test::stream_options(clip);
    o.max_lag_s = max_lag_s;
    o.rate = 0.0;  // as fast as the server answers (a lag of 60 s never skips a frame)
    const StreamReport report = stream_dataset(client, o);
    const nlohmann::json status = client.get_json("/v1/sessions/" + std::to_string(report.session));
    EXPECT_EQ(status["skipped_frames"], 0u);
    EXPECT_GT(status["keyframes"].get<std::size_t>(), 2u) << status.dump();
    return std::pair{status["slam"]["mapping_wait_ms"]["count"].get<std::size_t>(),
                     status["keyframes"].get<std::size_t>()};
  };
  const auto [waits, keyframes] = mapping_waits(std::nullopt);
  const std::size_t real_time_waits = mapping_waits(60.0).first;
  EXPECT_GE(waits + 1, keyframes);  // after every keyframe but perhaps the last
  EXPECT_EQ(real_time_waits, 0u);
}

}  // namespace
}  // namespace orbatlas
