// Named clients, roles and session ownership: before, anyone with the
// one token could send frames to or finish anyone's session.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include <filesystem>
#include <fstream>

#include "client/api/server_client.h"
#include "core/common/error.h"
#include "server/http/client_credentials.h"
#include "tests/support/server_test_fixture.h"
#include "tests/support/server_test_reply.h"

namespace orbatlas {
namespace {

using json = nlohmann::json;

std::string hex(const ClientCredentials::Digest& d) {
  static const char* digits = "0123456789abcdef";
  std::string out;
  for (const unsigned char b : d) {
    out += digits[b >> 4];
    out += digits[b & 15];
  }
  return out;
}

struct ClientsFile {
  std::filesystem::path path =
      std::filesystem::temp_directory_path() / ("orbatlas_test_clients_" + std::to_string(::getpid()) + ".txt");
  explicit ClientsFile(const std::string& text) { std::ofstream(path) << text; }
  ~ClientsFile() { std::filesystem::remove(path); }
};

std::string line(const std::string& name, const std::string& role, const std::string& token) {
  return name + " " + role + " sha256:" + hex(sha256(token)) + "\n";
}

std::string error_of(const std::string& text) {
  ClientsFile file(text);
  try {
    ClientCredentials::from_file(file.path);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(ClientCredentials, DigestsAreSha256AndTheFileIsChecked) {
  // FIPS 180-2's first example; `printf %s abc | sha256sum` prints the same.
  EXPECT_EQ(hex(sha256("abc")), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_NE(error_of("robot device sha256:1234\n").find(":1: the token is given as sha256:"), std::string::npos);
  EXPECT_NE(error_of("# fleet\n\nrobot pilot sha256:" + hex(sha256("x")) + "\n").find(":3: role 'pilot'"),
            std::string::npos);
  EXPECT_NE(
      error_of(line("robot", "device", "a") + line("robot", "reader", "b")).find(":2: client 'robot' is named twice"),
      std::string::npos);
  EXPECT_NE(error_of("robot device\n").find(":1: expected 'name role sha256:<hex>'"), std::string::npos);
  EXPECT_NE(error_of("ro/bot device sha256:" + hex(sha256("x")) + "\n").find("a client name is"), std::string::npos);
  EXPECT_NE(error_of("# nobody\n").find("no client"), std::string::npos);

  ClientsFile file("# name role token\n" + line("robot", "device", "t-robot") + line("ops", "operator", "t-ops") +
                   "dash reader sha256:" + hex(sha256("t-dash")) + "  # the dashboard\n");
  const ClientCredentials c = ClientCredentials::from_file(file.path);
  EXPECT_EQ(c.size(), 3u);
  EXPECT_EQ(c.authenticate("Bearer t-robot")->name, "robot");
  EXPECT_EQ(c.authenticate("bearer t-ops")->role, ClientRole::kOperator);
  EXPECT_EQ(c.authenticate("BEARER  t-dash ")->name, "dash");
  EXPECT_FALSE(c.authenticate("Bearer t-rob"));
  EXPECT_FALSE(c.authenticate("Basic t-robot"));
  EXPECT_FALSE(c.authenticate("Bearer "));
  EXPECT_FALSE(c.authenticate(""));
}

TEST(ClientCredentials, RolesAllowWhatTheirNamesSay) {
  for (const auto role : {ClientRole::kReader, ClientRole::kDevice, ClientRole::kOperator}) {
    EXPECT_TRUE(role_allows(role, "GET", "/v1/sessions"));
    EXPECT_TRUE(role_allows(role, "GET", "/v1/maps/3/points.bin"));
  }
  EXPECT_FALSE(role_allows(ClientRole::kReader, "POST", "/v1/sessions"));
  EXPECT_FALSE(role_allows(ClientRole::kReader, "POST", "/v1/localize"));
  EXPECT_TRUE(role_allows(ClientRole::kDevice, "POST", "/v1/sessions"));
  EXPECT_TRUE(role_allows(ClientRole::kDevice, "POST", "/v1/sessions/12/frames"));
  EXPECT_TRUE(role_allows(ClientRole::kDevice, "POST", "/v1/sessions/12/imu"));
  EXPECT_TRUE(role_allows(ClientRole::kDevice, "POST", "/v1/sessions/12/finish"));
  EXPECT_TRUE(role_allows(ClientRole::kDevice, "POST", "/v1/localize"));
  EXPECT_FALSE(role_allows(ClientRole::kDevice, "POST", "/v1/uploads"));
  EXPECT_FALSE(role_allows(ClientRole::kDevice, "DELETE", "/v1/sessions/12"));
  EXPECT_FALSE(role_allows(ClientRole::kDevice, "POST", "/v1/sessions/12/frames/x"));
  EXPECT_TRUE(role_allows(ClientRole::kOperator, "POST", "/v1/uploads"));
}

TEST(ServerClients, ASessionIsItsClientsAndEachRoleDoesWhatItMay) {
  test::TempDbPath db("clients");
  ClientsFile file(line("robot1", "device", "t1") + line("robot2", "device", "t2") + line("dash", "reader", "t3") +
                   line("ops", "operator", "t4"));
  HttpApiOptions api;
  api.clients = ClientCredentials::from_file(file.path);
  test::TestServer server(test::server_options(db.path), api);
  ServerClient robot1(server.url(), "t1"), robot2(server.url(), "t2"), dash(server.url(), "t3"),
      ops(server.url(), "t4");
  const std::uint64_t id = robot1.create_session("euroc/stereo_inertial", "robot1's");
  const std::string path = "/v1/sessions/" + std::to_string(id);
  const std::string imu = R"({"samples": [[1000, 0, 0, 0, 0, 0, 9.8]]})";
  // Another device cannot drive it or end it (before: both worked).
  EXPECT_REPLY(robot2.http().Post(path + "/imu", imu, "application/json"), 403, "forbidden");
  EXPECT_REPLY(robot2.http().Post(path + "/frames", "x", "application/octet-stream"), 403, "forbidden");
  EXPECT_REPLY(robot2.http().Post(path + "/finish", "", "application/json"), 403, "forbidden");
  // Not even an operator sends its frames; an operator may end it.
  EXPECT_REPLY(ops.http().Post(path + "/imu", imu, "application/json"), 403, "forbidden");
  EXPECT_REPLY(robot1.http().Post(path + "/imu", imu, "application/json"), 200, "");
  // A reader reads, and sees whose it is; it starts nothing.
  const json status = dash.get_json(path);
  EXPECT_EQ(status["client"], "robot1");
  EXPECT_EQ(status["imu_samples"], 1);
  EXPECT_REPLY(dash.http().Post("/v1/sessions", R"({"config": "euroc/stereo"})", "application/json"), 403, "forbidden");
  // A device uploads nothing.
  EXPECT_REPLY(robot1.http().Post("/v1/uploads?name=x", "tar", "application/x-tar"), 403, "forbidden");
  EXPECT_REPLY(ops.http().Post(path + "/finish", "", "application/json"), 200, "");
  EXPECT_EQ(dash.get_json(path)["state"], "finished");
  EXPECT_REPLY(ServerClient(server.url()).http().Get("/v1/sessions"), 401, "unauthorized");
  // Requests are counted by client and role, once answered: the server counts
  // a request after its reply is written, so the last one may be counted a
  // moment after its client read the reply (looked at again for up to 5 s).
  const char* unauthenticated = R"(orbatlas_http_requests_total{client="unauthenticated",role="-",status="4xx"} 1)";
  std::string metrics = ops.get_text("/metrics");
  for (int k = 0; k < 50 && metrics.find(unauthenticated) == std::string::npos; ++k) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    metrics = ops.get_text("/metrics");
  }
  EXPECT_NE(metrics.find(R"(orbatlas_http_requests_total{client="robot2",role="device",status="4xx"} 3)"),
            std::string::npos)
      << metrics.substr(metrics.find("orbatlas_http_requests_total"), 600);
  EXPECT_NE(metrics.find(unauthenticated), std::string::npos);
}

}  // namespace
}  // namespace orbatlas
