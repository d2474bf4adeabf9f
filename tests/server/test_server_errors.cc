// Every route's error paths: each bad request gets the right 4xx with a JSON
// error body, the server stays up, and the stored data does not change.
#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include "client/api/server_client.h"
#include "core/persistence/atlas_store.h"
#include "tests/support/server_test_fixture.h"
#include "tests/support/server_test_reply.h"
#include "tests/support/slam_test_clip.h"

namespace orbatlas {
namespace {

using json = nlohmann::json;
using test::png_of;

httplib::MultipartFormDataItems frame_form(const std::string& t_ns, const std::string& left, const std::string& right) {
  return {{"t_ns", t_ns, "", ""}, {"left", left, "l.png", "image/png"}, {"right", right, "r.png", "image/png"}};
}

// The state a client can see; it must be the same before and after the bad requests.
json visible_state(ServerClient& client) {
  json s = client.get_json("/v1/sessions");
  for (auto& session : s["sessions"]) session.erase("tracking_ms");
  return {{"sessions", s}, {"maps", client.get_json("/v1/maps")}};
}

TEST(ServerErrors, EveryRouteAnswersBadRequestsWithAJsonErrorAndChangesNothing) {
  const auto clip = test::simulated_clip("MH_01", 40.0, 1.0);
  test::ClipCleanup cleanup{clip};
  const auto frames = test::stereo_frames(clip);
  const std::string left = png_of(cv::imread(frames[0].left.string(), cv::IMREAD_GRAYSCALE));
  const std::string right = png_of(cv::imread(frames[0].right.string(), cv::IMREAD_GRAYSCALE));
  test::TempDbPath db("errors");
  HttpApiOptions api;
  api.max_body_bytes = 4u << 20;
  test::TestServer server(test::server_options(db.path), api);
  ServerClient client(server.url());
  httplib::Client& http = client.http();

  // One session with a few good frames, so that there is state to protect.
  const std::uint64_t id = client.create_session("euroc/stereo", "guarded");
  for (std::size_t i = 0; i < 5; ++i) {
    const auto reply = client.post_frame(id, frames[i].t_ns, cv::imread(frames[i].left.string(), cv::IMREAD_GRAYSCALE),
                                         cv::imread(frames[i].right.string(), cv::IMREAD_GRAYSCALE));
    ASSERT_TRUE(reply["tracked"].get<bool>());
  }
  const std::string sid = "/v1/sessions/" + std::to_string(id);
  const std::string next_t = std::to_string(frames[5].t_ns);
  const json before = visible_state(client);

  // POST /v1/sessions
  EXPECT_REPLY(http.Post("/v1/sessions", "{not json", "application/json"), 400, "bad_json");
  EXPECT_REPLY(http.Post("/v1/sessions", "[1,2]", "application/json"), 400, "bad_request");
  EXPECT_REPLY(http.Post("/v1/sessions", "{}", "application/json"), 400, "bad_request");
  EXPECT_REPLY(http.Post("/v1/sessions", R"({"config": 5})", "application/json"), 400, "bad_request");
  EXPECT_REPLY(http.Post("/v1/sessions", R"({"config": "nope/none"})", "application/json"), 404, "not_found");
  EXPECT_REPLY(http.Post("/v1/sessions", R"({"config": "../../etc/passwd"})", "application/json"), 400, "bad_request");
  EXPECT_REPLY(http.Post("/v1/sessions", R"({"config": "euroc/mono", "sensor": "stereo"})", "application/json"), 400,
               "bad_config");
  EXPECT_REPLY(http.Post("/v1/sessions", R"({"config": "euroc/stereo", "sensor": "sonar"})", "application/json"), 400,
               "bad_request");
  EXPECT_REPLY(http.Post("/v1/sessions", R"({"config": "euroc/stereo", "max_lag_s": "soon"})", "application/json"), 400,
               "bad_request");
  EXPECT_REPLY(http.Post("/v1/sessions", R"({"config": "euroc/stereo", "max_lag_s": -0.1})", "application/json"), 400,
               "bad_request");
  EXPECT_REPLY(http.Post("/v1/sessions", R"({"config": "euroc/stereo", "max_lag_s": 3600})", "application/json"), 400,
               "bad_request");
  EXPECT_REPLY(http.Post("/v1/sessions", R"({"settings_yaml": "%YAML:1.0\nCamera1.fx: [oops"})", "application/json"),
               400, "bad_config");
  // GET /v1/sessions/{id}
  EXPECT_REPLY(http.Get("/v1/sessions/999"), 404, "not_found");
  EXPECT_REPLY(http.Get("/v1/sessions/99999999999999999999999"), 404, "not_found");
  EXPECT_REPLY(http.Get("/v1/sessions/abc"), 404, "not_found");
  // POST /v1/sessions/{id}/frames
  EXPECT_REPLY(http.Post("/v1/sessions/999/frames", frame_form(next_t, left, right)), 404, "not_found");
  EXPECT_REPLY(http.Post(sid + "/frames", "{}", "application/json"), 400, "bad_request");
  EXPECT_REPLY(http.Post(sid + "/frames", frame_form("soon", left, right)), 400, "bad_request");
  EXPECT_REPLY(http.Post(sid + "/frames", httplib::MultipartFormDataItems{{"t_ns", next_t, "", ""}}), 400,
               "bad_request");
  // A stereo session given one image.
  EXPECT_REPLY(http.Post(sid + "/frames", httplib::MultipartFormDataItems{{"t_ns", next_t, "", ""},
                                                                          {"left", left, "l.png", "image/png"}}),
               422, "bad_input");
  EXPECT_REPLY(http.Post(sid + "/frames", frame_form(std::to_string(frames[2].t_ns), left, right)), 422, "bad_input");
  EXPECT_REPLY(http.Post(sid + "/frames", frame_form(next_t, left.substr(0, left.size() / 2), right)), 422,
               "bad_input");
  EXPECT_REPLY(http.Post(sid + "/frames", frame_form(next_t, "hello", right)), 422, "bad_input");
  const std::string small = png_of(cv::Mat(240, 376, CV_8UC1, cv::Scalar(9)));
  EXPECT_REPLY(http.Post(sid + "/frames", frame_form(next_t, small, small)), 422, "bad_input");
  const std::string deep = png_of(cv::Mat(480, 752, CV_16UC1, cv::Scalar(900)));
  EXPECT_REPLY(http.Post(sid + "/frames", frame_form(next_t, deep, deep)), 422, "bad_input");
  auto raw_form = frame_form(next_t, std::string(100, '\1'), std::string(100, '\1'));
  raw_form.push_back({"width", "752", "", ""});
  raw_form.push_back({"height", "480", "", ""});
  EXPECT_REPLY(http.Post(sid + "/frames", raw_form), 422, "bad_input");
  // One application/octet-stream body of raw pixels (left, then right), its size in the query.
  const std::string pair(2u * 752 * 480, '\7');
  const auto raw_frame = [&](const std::string& query, const std::string& body) {
    return http.Post(sid + "/frames" + query, body, "application/octet-stream");
  };
  EXPECT_REPLY(
      http.Post("/v1/sessions/999/frames?t_ns=" + next_t + "&width=752&height=480", pair, "application/octet-stream"),
      404, "not_found");
  EXPECT_REPLY(raw_frame("?width=752&height=480", pair), 400, "bad_request");                    // no t_ns
  EXPECT_REPLY(raw_frame("?t_ns=soon&width=752&height=480", pair), 400, "bad_request");          // not an integer
  EXPECT_REPLY(raw_frame("?t_ns=" + next_t + "&width=752", pair), 400, "bad_request");           // no height
  EXPECT_REPLY(raw_frame("?t_ns=" + next_t + "&width=0&height=480", pair), 400, "bad_request");  // no image
  EXPECT_REPLY(raw_frame("?t_ns=" + next_t + "&width=376&height=240", pair), 422, "bad_input");  // not the camera's
  EXPECT_REPLY(raw_frame("?t_ns=" + next_t + "&width=752&height=480", pair.substr(1)), 422, "bad_input");
  EXPECT_REPLY(raw_frame("?t_ns=" + next_t + "&width=752&height=480", pair.substr(pair.size() / 2)), 422,
               "bad_input");  // one image for a stereo session
  EXPECT_REPLY(raw_frame("?t_ns=" + std::to_string(frames[2].t_ns) + "&width=752&height=480", pair), 422,
               "bad_input");  // time going backwards
  EXPECT_REPLY(raw_frame("?t_ns=" + next_t + "&width=752&height=480", ""), 422, "bad_input");
  EXPECT_REPLY(http.Post(sid + "/frames", frame_form(next_t, std::string(5u << 20, 'x'), right)), 413, "too_large");
  // POST /v1/sessions/{id}/imu
  EXPECT_REPLY(http.Post("/v1/sessions/999/imu", R"({"samples": []})", "application/json"), 404, "not_found");
  EXPECT_REPLY(http.Post(sid + "/imu", "{", "application/json"), 400, "bad_json");
  EXPECT_REPLY(http.Post(sid + "/imu", R"({"samples": [[1, 2, 3]]})", "application/json"), 400, "bad_request");
  EXPECT_REPLY(
      http.Post(sid + "/imu", R"({"samples": [[10, 0,0,0, 0,0,9.8], [5, 0,0,0, 0,0,9.8]]})", "application/json"), 422,
      "bad_input");
  EXPECT_REPLY(
      http.Post(sid + "/imu", R"({"samples": [[0, 0,0,0, 0,0,9.8], [1, 0,0,0, 0,0,9.8], [1, 0,0,0, 0,0,9.8]]})",
                "application/json"),
      422, "bad_input");
  EXPECT_REPLY(http.Post(sid + "/imu", R"({"samples": [[0, 0,0,0, 0,0,"x"]]})", "application/json"), 400,
               "bad_request");
  // GET /v1/sessions/{id}/trajectory, POST /v1/sessions/{id}/finish
  EXPECT_REPLY(http.Get("/v1/sessions/999/trajectory"), 404, "not_found");
  EXPECT_REPLY(http.Post("/v1/sessions/999/finish", "{}", "application/json"), 404, "not_found");
  // Maps
  EXPECT_REPLY(http.Get("/v1/maps/999"), 404, "not_found");
  EXPECT_REPLY(http.Get("/v1/maps/999/points.ply"), 404, "not_found");
  // The viewer's data routes
  EXPECT_REPLY(http.Get("/v1/maps/999/keyframes"), 404, "not_found");
  EXPECT_REPLY(http.Get("/v1/maps/999/points.bin"), 404, "not_found");
  for (const char* max : {"0", "-1", "x", "12x", "5000001", ""})
    EXPECT_REPLY(http.Get(std::string("/v1/maps/0/points.bin?max=") + max), 400, "bad_request");
  EXPECT_REPLY(http.Post("/v1/live", "{}", "application/json"), 405, "method_not_allowed");
  EXPECT_REPLY(http.Get("/viewer/missing.js"), 404, "not_found");
  // Merges: read-only
  EXPECT_REPLY(http.Post("/v1/merges", "{}", "application/json"), 405, "method_not_allowed");
  EXPECT_REPLY(http.Delete("/v1/merges"), 405, "method_not_allowed");
  // Replicas: read-only, one list
  EXPECT_REPLY(http.Post("/v1/replicas", "{}", "application/json"), 405, "method_not_allowed");
  EXPECT_REPLY(http.Get("/v1/replicas/1"), 404, "not_found");
  // POST /v1/localize
  EXPECT_REPLY(http.Post("/v1/localize", "{}", "application/json"), 400, "bad_request");
  EXPECT_REPLY(http.Post("/v1/localize", httplib::MultipartFormDataItems{{"config", "euroc/stereo", "", ""}}), 400,
               "bad_request");
  EXPECT_REPLY(http.Post("/v1/localize", httplib::MultipartFormDataItems{{"image", left, "l.png", "image/png"}}), 400,
               "bad_request");
  EXPECT_REPLY(http.Post("/v1/localize", httplib::MultipartFormDataItems{{"config", "euroc/stereo", "", ""},
                                                                         {"image", "garbage", "l.png", "image/png"}}),
               422, "bad_input");
  EXPECT_REPLY(http.Post("/v1/localize", httplib::MultipartFormDataItems{{"config", "euroc/stereo", "", ""},
                                                                         {"map", "77", "", ""},
                                                                         {"image", left, "l.png", "image/png"}}),
               404, "not_found");
  // No such route; wrong method.
  EXPECT_REPLY(http.Get("/v2/everything"), 404, "not_found");
  EXPECT_REPLY(http.Delete(sid), 405, "method_not_allowed");

  // Alive, and nothing changed: the same sessions, frames and maps.
  EXPECT_EQ(client.get_json("/healthz")["status"], "ok");
  EXPECT_EQ(visible_state(client)["maps"], before["maps"]);
  const json after_sessions = visible_state(client)["sessions"];
  ASSERT_EQ(after_sessions["sessions"].size(), 1u);
  EXPECT_EQ(after_sessions["sessions"][0]["frames"], before["sessions"]["sessions"][0]["frames"]);
  EXPECT_EQ(after_sessions["sessions"][0]["keyframes"], before["sessions"]["sessions"][0]["keyframes"]);
  EXPECT_EQ(after_sessions["sessions"][0]["imu_samples"], 0);
  // The session goes on after all that: the next good frame tracks.
  const auto good = client.post_frame(id, frames[5].t_ns, cv::imread(frames[5].left.string(), cv::IMREAD_GRAYSCALE),
                                      cv::imread(frames[5].right.string(), cv::IMREAD_GRAYSCALE));
  EXPECT_TRUE(good["tracked"].get<bool>());
  // Finished: no more frames (409), finishing again is fine.
  client.finish_session(id);
  EXPECT_REPLY(http.Post(sid + "/frames", frame_form(std::to_string(frames[6].t_ns), left, right)), 409, "conflict");
  EXPECT_REPLY(http.Post(sid + "/finish", "{}", "application/json"), 200, "");
}

// A real-time session ("max_lag_s"): a frame that arrives further behind the
// sensor's clock than the lag allows is skipped, not tracked, and said so; the
// frames after it are tracked again as soon as they arrive on time.
TEST(ServerErrors, ARealTimeSessionSkipsAFrameThatArrivesTooLate) {
  const auto clip = test::simulated_clip("MH_01", 40.0, 1.0);
  test::ClipCleanup cleanup{clip};
  const auto frames = test::stereo_frames(clip);
  test::TempDbPath db("realtime");
  test::TestServer server(test::server_options(db.path));
  ServerClient client(server.url());
  const auto started = client.start_session("euroc/stereo", "realtime", "", "", 0.03);
  const std::uint64_t id = started.at("id").get<std::uint64_t>();
  const auto send = [&](std::size_t i) {
    return client.post_frame(id, frames[i].t_ns, cv::imread(frames[i].left.string(), cv::IMREAD_GRAYSCALE),
                             cv::imread(frames[i].right.string(), cv::IMREAD_GRAYSCALE));
  };
  EXPECT_FALSE(send(0)["skipped"].get<bool>());
  // Frame 1 was captured 50 ms after frame 0 and is sent 300 ms after it:
  // 250 ms late, more than the 30 ms allowed.
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  const auto late = send(1);
  EXPECT_TRUE(late["skipped"].get<bool>());
  EXPECT_FALSE(late["tracked"].get<bool>());
  // Frame 14 (700 ms after frame 0 in the sensor's time) arrives on time
  // again (unless tracking frame 0 took over 0.4 s).
  const auto on_time = send(14);
  EXPECT_FALSE(on_time["skipped"].get<bool>());
  EXPECT_TRUE(on_time["tracked"].get<bool>());
  const auto status = client.get_json("/v1/sessions/" + std::to_string(id));
  EXPECT_EQ(status["skipped_frames"], 1);
  EXPECT_EQ(status["frames"], 2);
  client.finish_session(id);
}

TEST(ServerErrors, TokenIsRequiredAndChecked) {
  test::TempDbPath db("token");
  HttpApiOptions api;
  api.token = "s3cret";
  test::TestServer server(test::server_options(db.path), api);
  {
    ServerClient anonymous(server.url());
    EXPECT_REPLY(anonymous.http().Get("/v1/sessions"), 401, "unauthorized");
    EXPECT_REPLY(anonymous.http().Post("/v1/sessions", R"({"config": "euroc/stereo"})", "application/json"), 401,
                 "unauthorized");
    EXPECT_REPLY(anonymous.http().Get("/metrics"), 401, "unauthorized");
    EXPECT_REPLY(anonymous.http().Get("/v1/merges"), 401, "unauthorized");
    EXPECT_REPLY(anonymous.http().Get("/healthz"), 200, "");  // health checks need no token
    // The viewer's page and scripts hold no data: no token; its data routes need it.
    EXPECT_REPLY(anonymous.http().Get("/"), 200, "");
    EXPECT_REPLY(anonymous.http().Get("/viewer/app.js"), 200, "");
    EXPECT_REPLY(anonymous.http().Get("/viewer/scene.js"), 200, "");
    EXPECT_REPLY(anonymous.http().Get("/viewer/three.min.js"), 200, "");
    EXPECT_REPLY(anonymous.http().Get("/v1/live"), 401, "unauthorized");
    EXPECT_REPLY(anonymous.http().Get("/v1/maps/0/keyframes"), 401, "unauthorized");
    EXPECT_REPLY(anonymous.http().Get("/v1/maps/0/points.bin"), 401, "unauthorized");
  }
  ServerClient wrong(server.url(), "s3cres");
  EXPECT_REPLY(wrong.http().Get("/v1/maps"), 401, "unauthorized");
  ServerClient right(server.url(), "s3cret");
  EXPECT_EQ(right.get_json("/v1/sessions")["sessions"].size(), 0u);  // nothing was created by the refused requests
  EXPECT_REPLY(right.http().Get("/v1/maps"), 200, "");
  // The scheme in any letter case (before: "bearer" was refused).
  httplib::Client lower(server.url());
  EXPECT_REPLY(lower.Get("/v1/maps", {{"Authorization", "bearer s3cret"}}), 200, "");
  EXPECT_REPLY(lower.Get("/v1/maps", {{"Authorization", "BEARER s3cret"}}), 200, "");
  EXPECT_REPLY(lower.Get("/v1/maps", {{"Authorization", "Basic s3cret"}}), 401, "unauthorized");
  EXPECT_REPLY(lower.Get("/v1/maps", {{"Authorization", "Bearers3cret"}}), 401, "unauthorized");
}

TEST(ServerErrors, DatabaseOfAnotherVocabularyIsRefusedAndKept) {
  test::TempDbPath db("vocab");
  // A database made for another vocabulary: the server refuses to open it.
  { AtlasStore::open(db.path, std::string(64, 'a')); }
  const auto size = std::filesystem::file_size(db.path);
  try {
    AtlasService service(test::server_options(db.path));
    FAIL() << "a database from another vocabulary was opened";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("vocabulary"), std::string::npos) << e.what();
  }
  EXPECT_EQ(std::filesystem::file_size(db.path), size);
}

}  // namespace
}  // namespace orbatlas
