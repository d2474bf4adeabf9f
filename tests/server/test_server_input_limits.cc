// Limits on what a client sends: uploads read files inside their own
// folder only, IMU values and batches are bounded, numbers do not wrap, and IMU
// alone does not hold a session past its idle timeout. Each failed before its fix.
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include <opencv2/imgcodecs.hpp>

#include "client/api/server_client.h"
#include "core/archive/tar_writer.h"
#include "tests/support/server_test_fixture.h"
#include "tests/support/server_test_reply.h"

namespace orbatlas {
namespace {

using json = nlohmann::json;
using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

// A TUM RGB-D recording whose rgb.txt names `colour` (depth/0.png is its own).
std::string tum_tar(const std::filesystem::path& dir, const std::string& colour) {
  std::filesystem::create_directories(dir / "rgb");
  std::filesystem::create_directories(dir / "depth");
  cv::imwrite((dir / "rgb" / "0.png").string(), cv::Mat(48, 64, CV_8UC3, cv::Scalar(90, 90, 90)));
  cv::imwrite((dir / "depth" / "0.png").string(), cv::Mat(48, 64, CV_16UC1, cv::Scalar(5000)));
  { std::ofstream(dir / "rgb.txt") << "# colour\n1.000000 rgb/0.png\n2.000000 " << colour << "\n"; }
  { std::ofstream(dir / "depth.txt") << "# depth\n1.000000 depth/0.png\n2.000000 depth/0.png\n"; }
  std::string tar;
  TarWriter writer([&](const char* d, std::size_t n) { tar.append(d, n); });
  for (const char* name : {"rgb.txt", "depth.txt", "rgb/0.png", "depth/0.png"}) writer.add_file(name, dir / name);
  writer.finish();
  return tar;
}

TEST(ServerInputLimits, AnUploadNamingFilesOutsideItsFolderIsRefusedWithTheLine) {
  test::TempDbPath db("confined");
  test::TestServer server(test::server_options(db.path));
  ServerClient client(server.url());
  const std::filesystem::path dir = db.path.string() + "_recording";
  for (const std::string& name :
       {std::string("/etc/passwd"), std::string("../../../../etc/passwd"), (dir / "rgb" / "0.png").string()}) {
    SCOPED_TRACE(name);
    const auto reply =
        client.http().Post("/v1/uploads?name=escape&config=euroc/rgbd", tum_tar(dir, name), "application/x-tar");
    ASSERT_TRUE(reply);
    EXPECT_EQ(reply->status, 422) << reply->body;
    EXPECT_NE(reply->body.find("rgb.txt:3"), std::string::npos) << reply->body;
    EXPECT_NE(reply->body.find("inside its own folder"), std::string::npos) << reply->body;
    EXPECT_EQ(reply->body.find(db.path.parent_path().string() + "/orbatlas"), std::string::npos)
        << "a server path in the message";
  }
  EXPECT_EQ(client.get_json("/v1/jobs")["jobs"].size(), 0u);
  std::filesystem::remove_all(dir);
}

TEST(ServerInputLimits, ImuValuesAndBatchesAreBounded) {
  test::TempDbPath db("imu_limits");
  test::TestServer server(test::server_options(db.path));
  ServerClient client(server.url());
  const std::uint64_t id = client.create_session("euroc/stereo_inertial", "imu limits");
  const std::string path = "/v1/sessions/" + std::to_string(id) + "/imu";
  // The probe's 1e308 rad/s: 422 naming the sample.
  EXPECT_REPLY(client.http().Post(path, R"({"samples": [[1000, 1e308, 0, 0, 0, 0, 9.8]]})", "application/json"), 422,
               "bad_input");
  EXPECT_REPLY(client.http().Post(path, R"({"samples": [[1000, 0, 0, 0, 0, -3e4, 9.8]]})", "application/json"), 422,
               "bad_input");
  // A real IMU's fast spin and hard knock are taken.
  EXPECT_REPLY(client.http().Post(path, R"({"samples": [[1000, 30, 0, 0, 0, 0, 150]]})", "application/json"), 200, "");
  // More samples than a batch takes: 413 before the values are looked at.
  std::string many = R"({"samples": [)";
  for (int i = 0; i < 20001; ++i) {
    if (i > 0) many += ',';
    many += '[';
    many += std::to_string(2000 + i);
    many += ",0,0,0,0,0,9.8]";
  }
  many += "]}";
  EXPECT_REPLY(client.http().Post(path, many, "application/json"), 413, "too_large");
  EXPECT_REPLY(client.http().Post(path, std::string(5u << 20, ' '), "application/json"), 413, "too_large");
  EXPECT_EQ(client.get_json("/v1/sessions/" + std::to_string(id))["imu_samples"], 1);
}

TEST(ServerInputLimits, ImuAloneDoesNotHoldASessionPastItsIdleTimeout) {
  test::TempDbPath db("imu_idle");
  AtlasServiceOptions options = test::server_options(db.path);
  options.idle_timeout_s = 0.5;
  test::TestServer server(options);
  ServerClient client(server.url());
  const std::uint64_t id = client.create_session("euroc/stereo_inertial", "imu only");
  // A batch every 0.1 s, no frame (before: the session stayed for as long as they came).
  json status;
  std::int64_t t = 1000;
  for (const auto until = Clock::now() + 5s; Clock::now() < until;) {
    client.http().Post("/v1/sessions/" + std::to_string(id) + "/imu",
                       "{\"samples\": [[" + std::to_string(t += 5000000) + ", 0, 0, 0, 0, 0, 9.8]]}",
                       "application/json");
    status = client.get_json("/v1/sessions/" + std::to_string(id));
    if (status["state"] != "active") break;
    std::this_thread::sleep_for(100ms);
  }
  EXPECT_EQ(status["state"], "finished") << status.dump();
  EXPECT_EQ(status.value("ended_by", ""), "idle_timeout");
}

TEST(ServerInputLimits, ANegativeMapIdIsABadRequest) {
  test::TempDbPath db("map_id");
  test::TestServer server(test::server_options(db.path));
  ServerClient client(server.url());
  httplib::MultipartFormDataItems form = {{"config", "euroc/stereo", "", ""},
                                          {"map", "-1", "", ""},
                                          {"image", std::string(16, 'x'), "image.png", "image/png"}};
  const auto reply = client.http().Post("/v1/localize", form);
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->status, 400) << reply->body;  // before: 404 for map 18446744073709551615
  EXPECT_NE(reply->body.find("'map'"), std::string::npos) << reply->body;
}

}  // namespace
}  // namespace orbatlas
