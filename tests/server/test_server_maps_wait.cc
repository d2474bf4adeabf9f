// A real-time session's frame waits for the atlas's maps at most the server's
// --max-maps-wait-ms while an edit holds them (AtlasServiceOptions::max_maps_wait_ms):
// past it the reply is untracked and says maps_busy, counted in the session's
// status and in /metrics and by the streaming client; a session that is not
// real-time waits for the edit.
#include <gtest/gtest.h>

#include <chrono>
#include <future>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <string>

#include "client/api/dataset_streamer.h"
#include "client/api/server_client.h"
#include "tests/support/server_test_fixture.h"
#include "tests/support/slam_test_clip.h"

namespace orbatlas {
namespace {

TEST(ServerMapsWait, ARealTimeFrameHeldPastTheBoundIsAnsweredMapsBusy) {
  const auto clip = test::simulated_clip("MH_01", 40.0, 1.0);
  test::ClipCleanup cleanup{clip};
  const auto frames = test::stereo_frames(clip);
  ASSERT_GE(frames.size(), 10u);
  test::TempDbPath db("maps_wait");
  AtlasServiceOptions options = test::server_options(db.path);
  EXPECT_EQ(options.max_maps_wait_ms, 50.0);  // the default
  options.max_maps_wait_ms = 40.0;
  options.merge_maps = false;
  test::TestServer server(options);
  ServerClient client(server.url());
  const auto post = [&](std::uint64_t session, std::size_t i) {
    return client.post_frame(session, frames[i].t_ns, cv::imread(frames[i].left.string(), cv::IMREAD_GRAYSCALE),
                             cv::imread(frames[i].right.string(), cv::IMREAD_GRAYSCALE));
  };
  // Real-time (a lag of 60 s never skips a frame here).
  const auto live = client.start_session("euroc/stereo", "live", {}, {}, 60.0).at("id").get<std::uint64_t>();
  for (std::size_t i = 0; i < 4; ++i) ASSERT_TRUE(post(live, i)["tracked"].get<bool>());
  {
    const auto edit = server.service().atlas().lock_maps_exclusive();
    const nlohmann::json held = post(live, 4);
    EXPECT_TRUE(held["maps_busy"].get<bool>()) << held.dump();
    EXPECT_FALSE(held["tracked"].get<bool>());
    EXPECT_FALSE(held.contains("T_w_b"));
    EXPECT_GE(held["maps_wait_ms"].get<double>(), 40.0);
    EXPECT_LT(held["maps_wait_ms"].get<double>(), 80.0);
  }
  const nlohmann::json next = post(live, 5);
  EXPECT_TRUE(next["tracked"].get<bool>()) << next.dump();
  EXPECT_FALSE(next["maps_busy"].get<bool>());
  const nlohmann::json status = client.get_json("/v1/sessions/" + std::to_string(live));
  EXPECT_EQ(status["maps_busy_frames"], 1u);
  EXPECT_EQ(status["frames"], 6u);
  EXPECT_EQ(status["request_ms"]["count"], 6u) << "the answered maps_busy frame counts in the latency";
  EXPECT_NE(client.get_text("/metrics").find("orbatlas_frames_maps_busy_total 1"), std::string::npos);
  client.finish_session(live);

  // Not real-time: the frame waits for the edit, however long it takes.
  const auto offline = client.create_session("euroc/stereo", "offline");
  ASSERT_TRUE(post(offline, 0)["tracked"].get<bool>());
  auto edit = server.service().atlas().lock_maps_exclusive();
  ServerClient second(server.url());
  auto waiting = std::async(std::launch::async, [&] {
    return second.post_frame(offline, frames[1].t_ns, cv::imread(frames[1].left.string(), cv::IMREAD_GRAYSCALE),
                             cv::imread(frames[1].right.string(), cv::IMREAD_GRAYSCALE));
  });
  EXPECT_EQ(waiting.wait_for(std::chrono::milliseconds(300)), std::future_status::timeout);
  edit.unlock();
  const nlohmann::json waited = waiting.get();
  EXPECT_TRUE(waited["tracked"].get<bool>()) << waited.dump();
  EXPECT_FALSE(waited["maps_busy"].get<bool>());
  client.finish_session(offline);
}

// `orbatlas stream` counts the replies that say maps_busy (StreamReport,
// its --stats and --frame-log): here one frame is posted while an edit holds
// the maps.
TEST(ServerMapsWait, TheStreamingClientCountsTheMapsBusyReplies) {
  const auto clip = test::simulated_clip("MH_01", 40.0, 1.0);
  test::ClipCleanup cleanup{clip};
  test::TempDbPath db("maps_wait_stream");
  AtlasServiceOptions options = test::server_options(db.path);
  options.merge_maps = false;
  test::TestServer server(options);
  ServerClient client(server.url());
  StreamOptions o = test::stream_options(clip);
  o.max_lag_s = 60.0;  // real-time, never skipped here
  std::size_t next = 0;
  std::optional<decltype(server.service().atlas().lock_maps_exclusive())> edit;
  o.stop = [&] {
    if (next == 4) edit.emplace(server.service().atlas().lock_maps_exclusive());  // held while frame 4 is answered
    if (next == 5) edit.reset();
    ++next;
    return false;
  };
  const StreamReport report = stream_dataset(client, o);
  EXPECT_EQ(report.maps_busy_frames, 1u);
  EXPECT_EQ(report.tracked, report.frames - 1);
  ASSERT_GT(report.frame_timings.size(), 5u);
  EXPECT_TRUE(report.frame_timings[4].maps_busy);
  EXPECT_FALSE(report.frame_timings[5].maps_busy);
}

}  // namespace
}  // namespace orbatlas
