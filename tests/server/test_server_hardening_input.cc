// What an outside probe of the server found, each as a test that fails on
// the code before its fix: requests refused before the work they would cause
// (image headers, limits, timestamps, names), inline settings parsed in
// memory, and --config meaning the same in every client command.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "client/api/server_client.h"
#include "core/common/data_paths.h"
#include "core/io/settings.h"
#include "server/http/image_decode.h"
#include "tests/support/server_probes.h"
#include "tests/support/server_test_fixture.h"
#include "tests/support/server_test_reply.h"

namespace orbatlas {
namespace {

using json = nlohmann::json;
using test::settings_text;

// A PNG header declaring a width x height 8-bit grey image, with no pixel data.
std::string png_header(std::uint32_t width, std::uint32_t height) {
  std::string b = "\x89PNG\r\n\x1a\n";
  b += std::string("\0\0\0\x0d", 4) + "IHDR";
  for (const std::uint32_t v : {width, height})
    for (int shift = 24; shift >= 0; shift -= 8) b += static_cast<char>((v >> shift) & 0xff);
  b += std::string("\x08\x00\x00\x00\x00", 5) + std::string(4, '\0');  // depth 8, grey; a CRC
  return b;
}

TEST(ServerHardening, RequestsAreRefusedBeforeTheWorkTheyWouldCause) {
  test::TempDbPath db("limits");
  test::TestServer server(test::server_options(db.path));
  ServerClient client(server.url());
  httplib::Client& http = client.http();
  const std::uint64_t id = client.create_session("euroc/stereo", "target");
  const std::string sid = "/v1/sessions/" + std::to_string(id);
  const auto form = [](const std::string& t, const std::string& left, const std::string& right) {
    return httplib::MultipartFormDataItems{
        {"t_ns", t, "", ""}, {"left", left, "l.png", "image/png"}, {"right", right, "r.png", "image/png"}};
  };

  // A small PNG declaring 16384 x 16384 pixels: refused from its header (before:
  // decoded first, +524 MB of resident memory).
  const std::string bomb = png_header(16384, 16384);
  EXPECT_REPLY(http.Post(sid + "/frames", form("1000", bomb, bomb)), 422, "bad_input");
  auto reply = http.Post(sid + "/frames", form("1000", bomb, bomb));
  ASSERT_TRUE(reply);
  EXPECT_NE(reply->body.find("refused before decoding"), std::string::npos) << reply->body;
  EXPECT_REPLY(http.Post("/v1/localize", httplib::MultipartFormDataItems{{"config", "euroc/stereo", "", ""},
                                                                         {"image", bomb, "i.png", "image/png"}}),
               422, "bad_input");
  EXPECT_EQ(encoded_image_size(bomb), cv::Size(16384, 16384));

  // A raw width past 32 bits (before: truncated to 752 and accepted).
  auto raw = form("1000", std::string(752 * 480, '\1'), std::string(752 * 480, '\1'));
  raw.push_back({"width", "4294968048", "", ""});
  raw.push_back({"height", "480", "", ""});
  EXPECT_REPLY(http.Post(sid + "/frames", raw), 400, "bad_request");

  // Timestamps that wrap or block every later frame.
  const cv::Mat grey(480, 752, CV_8UC1, cv::Scalar(90));
  const std::string png = test::png_of(grey);
  EXPECT_REPLY(http.Post(sid + "/frames", form("9223372036854775807", png, png)), 422, "bad_input");
  EXPECT_REPLY(http.Post(sid + "/frames", form("-5", png, png)), 422, "bad_input");
  EXPECT_REPLY(http.Post(sid + "/imu", R"({"samples": [[9223372036854775808, 0,0,0, 0,0,9.8]]})", "application/json"),
               422, "bad_input");
  EXPECT_REPLY(http.Post(sid + "/imu", R"({"samples": [[18446744073709551615, 0,0,0, 0,0,9.8]]})", "application/json"),
               422, "bad_input");
  EXPECT_EQ(client.post_frame(id, 1'000'000'000, grey, grey)["t_ns"], 1'000'000'000);  // later frames still come in

  // Settings that would fail at the first frame with bad_alloc (500).
  std::string yaml = settings_text("euroc/stereo");
  const auto at = yaml.find("ORBextractor.nFeatures: 1200");
  ASSERT_NE(at, std::string::npos);
  yaml.replace(at, std::string("ORBextractor.nFeatures: 1200").size(), "ORBextractor.nFeatures: 1000000000");
  EXPECT_REPLY(http.Post("/v1/sessions", json{{"settings_yaml", yaml}}.dump(), "application/json"), 400, "bad_config");

  // Names: at most 200 bytes of UTF-8 text (before: 5 MB stored and listed).
  EXPECT_REPLY(http.Post("/v1/sessions", json{{"config", "euroc/stereo"}, {"name", std::string(5u << 20, 'n')}}.dump(),
                         "application/json"),
               400, "bad_request");
  EXPECT_REPLY(http.Post("/v1/sessions", R"({"config": "euroc/stereo", "name": "tab\there"})", "application/json"), 400,
               "bad_request");
  EXPECT_REPLY(http.Post("/v1/uploads?name=%FF%FE", "x", "application/x-tar"), 400, "bad_request");
  EXPECT_REPLY(http.Post("/v1/sessions", R"({"config": "euroc/stereo", "name": "Halle 3 – Süd"})", "application/json"),
               201, "");
  EXPECT_EQ(client.get_json("/v1/sessions")["sessions"].size(), 2u);
}

TEST(ServerHardening, InlineSettingsNeverTouchAFile) {
  // Before: written to /tmp/orbatlas-settings-<pid>-<n>.yaml, following a
  // planted symlink. Now parsed in memory: the planted target keeps its text.
  test::TempDbPath db("settings");
  const auto target = std::filesystem::temp_directory_path() / ("orbatlas_test_target_" + std::to_string(::getpid()));
  { std::ofstream(target) << "keep me\n"; }
  std::vector<std::filesystem::path> planted;
  for (int n = 0; n < 4; ++n) {
    planted.push_back(std::filesystem::temp_directory_path() /
                      ("orbatlas-settings-" + std::to_string(::getpid()) + "-" + std::to_string(n) + ".yaml"));
    std::error_code ec;
    std::filesystem::remove(planted.back(), ec);
    std::filesystem::create_symlink(target, planted.back());
  }
  {
    test::TestServer server(test::server_options(db.path));
    ServerClient client(server.url());
    const auto reply = client.post_json("/v1/sessions", {{"settings_yaml", settings_text("euroc/stereo")}});
    EXPECT_EQ(reply["session"]["config"], "inline");
  }
  std::ifstream in(target);
  std::string text((std::istreambuf_iterator<char>(in)), {});
  EXPECT_EQ(text, "keep me\n");
  for (const auto& p : planted) std::filesystem::remove(p);
  std::filesystem::remove(target);
}

// --config means the same in every client command: a settings file on this
// machine is sent as its text, anything else is a name the server knows (before:
// `orbatlas stream --config config/euroc/stereo.yaml` got 400 from the server).
TEST(ServerHardening, ConfigIsANameOrALocalSettingsFileInEveryCommand) {
  const std::filesystem::path file = shipped_config_dir() / "euroc" / "stereo.yaml";
  const SettingsChoice from_file = choose_settings(file.string());
  EXPECT_TRUE(from_file.config.empty());
  EXPECT_NE(from_file.settings_yaml.find("Camera1.fx"), std::string::npos);
  const SettingsChoice by_name = choose_settings("euroc/stereo");
  EXPECT_EQ(by_name.config, "euroc/stereo");
  EXPECT_TRUE(by_name.settings_yaml.empty());
  EXPECT_THROW(choose_settings("no/such/settings.yaml"), Error);  // a typo is named here, not sent

  test::TempDbPath db("config_choice");
  test::TestServer server(test::server_options(db.path));
  ServerClient client(server.url());
  const json started = client.start_session(file.string(), "from a file");
  EXPECT_EQ(started["session"]["sensor"], "stereo") << started.dump();
  client.finish_session(started["id"].get<std::uint64_t>());
  const json by_config = client.start_session("euroc/stereo", "by name");
  EXPECT_EQ(by_config["session"]["sensor"], "stereo") << by_config.dump();
  client.finish_session(by_config["id"].get<std::uint64_t>());
  // An upload's body is the recording: a settings file is refused by the client, saying so.
  const std::filesystem::path recording = db.path.string() + "_recording";
  std::filesystem::create_directories(recording / "mav0");
  try {
    client.upload(recording, file.string());
    ADD_FAILURE() << "an upload took a settings file";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("config name"), std::string::npos) << e.what();
  }
  std::filesystem::remove_all(recording);
}

}  // namespace
}  // namespace orbatlas
