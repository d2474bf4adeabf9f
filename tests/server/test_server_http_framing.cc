// HTTP framing on the wire: what an outside probe sent as raw bytes,
// each a test that failed before the fix. After a reply the server sends before
// a body was read, or to a request that did not parse, the connection is closed
// for real (the reply says so once) and nothing that followed is run as a
// request; encodings the server does not take are refused; stalls get 408.
#include <gtest/gtest.h>

#include <iostream>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <memory>
#include <thread>
#include <vector>

#include "client/api/server_client.h"
#include "tests/support/raw_http.h"
#include "tests/support/server_test_fixture.h"

namespace orbatlas {
namespace {

using json = nlohmann::json;
using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

int port_of(const std::string& url) { return std::stoi(url.substr(url.rfind(':') + 1)); }

// Sends `bytes` on a fresh connection and reads until the server closes it
// (or 3 s without a byte).
test::RawConnection::Received send_and_read(int port, const std::string& bytes,
                                            std::chrono::milliseconds quiet = 3000ms) {
  test::RawConnection c(port);
  EXPECT_TRUE(c.connected());
  c.send(bytes);
  return c.read_until_closed(quiet);
}

// One reply, saying `Connection: close` once and no Keep-Alive, then closed.
void expect_one_closing_reply(const test::RawConnection::Received& r, const std::string& status) {
  EXPECT_EQ(r.text.substr(0, 12), "HTTP/1.1 " + status) << r.text.substr(0, 300);
  EXPECT_EQ(test::occurrences(r.text, "HTTP/1.1 "), 1) << "a second reply: a request was read from unread bytes\n"
                                                       << r.text;
  EXPECT_EQ(test::occurrences(r.text, "Connection: close"), 1) << r.text.substr(0, 400);
  EXPECT_EQ(r.text.find("Keep-Alive"), std::string::npos) << r.text.substr(0, 400);
  EXPECT_TRUE(r.closed) << "the connection stayed open";
}

TEST(ServerHttpFraming, ABodyRefusedUnreadIsNeverRunAsARequest) {
  test::TempDbPath db("smuggle");
  test::TestServer server(test::server_options(db.path));
  const int port = port_of(server.url());
  // 413 (the probe's bytes): the "body" is a second request.
  const std::string smuggled = "GET /v1/jobs HTTP/1.1\r\n\r\n";
  const auto r =
      send_and_read(port,
                    "POST /v1/sessions HTTP/1.1\r\nContent-Type: application/json\r\nContent-Length: 68157440\r\n"
                    "\r\n" +
                        smuggled);
  expect_one_closing_reply(r, "413");
  EXPECT_EQ(r.text.find("\"jobs\""), std::string::npos) << r.text;
}

TEST(ServerHttpFraming, ABodyRefusedForItsTokenIsNeverRunWithTheTokenItCarries) {
  test::TempDbPath db("smuggle_token");
  HttpApiOptions api;
  api.token = "s3cret";
  test::TestServer server(test::server_options(db.path), api);
  const std::string inner =
      "POST /v1/sessions HTTP/1.1\r\nAuthorization: Bearer s3cret\r\nContent-Type: application/json\r\n"
      "Content-Length: 27\r\n\r\n{\"config\": \"euroc/stereo\"}";
  const auto r = send_and_read(port_of(server.url()), "POST /v1/sessions HTTP/1.1\r\nContent-Length: " +
                                                          std::to_string(inner.size()) + "\r\n\r\n" + inner);
  expect_one_closing_reply(r, "401");
  ServerClient client(server.url(), "s3cret");
  EXPECT_EQ(client.get_json("/v1/sessions")["sessions"].size(), 0u) << "the body's request was run";
}

TEST(ServerHttpFraming, AMalformedRequestLineClosesTheConnection) {
  test::TempDbPath db("desync");
  test::TestServer server(test::server_options(db.path));
  ServerClient client(server.url());
  const std::uint64_t id = client.create_session("euroc/stereo", "desync");
  // The probe's bytes: a bad line, then a line that finished the session.
  const auto r = send_and_read(port_of(server.url()), "FOO / HTTP/1.1\r\nPOST /v1/sessions/" + std::to_string(id) +
                                                          "/finish HTTP/1.1\r\nContent-Length: 0\r\n\r\n");
  expect_one_closing_reply(r, "400");
  EXPECT_EQ(client.get_json("/v1/sessions/" + std::to_string(id))["state"], "active");
  // A header line over httplib's 8 KB: the same.
  const auto long_header =
      send_and_read(port_of(server.url()), "GET /healthz HTTP/1.1\r\nX-Long: " + std::string(9000, 'a') +
                                               "\r\n\r\nPOST /v1/sessions/" + std::to_string(id) +
                                               "/finish HTTP/1.1\r\nContent-Length: 0\r\n\r\n");
  EXPECT_EQ(test::occurrences(long_header.text, "HTTP/1.1 "), 1) << long_header.text;
  EXPECT_TRUE(long_header.closed);
  EXPECT_EQ(client.get_json("/v1/sessions/" + std::to_string(id))["state"], "active");
}

TEST(ServerHttpFraming, HeadersOverTheLimitGet431AndAClosedConnection) {
  test::TempDbPath db("headers");
  test::TestServer server(test::server_options(db.path));
  std::string many;
  for (int i = 0; i < 2000; ++i) many += "X-H" + std::to_string(i) + ": 1234567890\r\n";  // ~40 KB in short lines
  const auto r = send_and_read(port_of(server.url()), "GET /healthz HTTP/1.1\r\n" + many + "\r\n");
  expect_one_closing_reply(r, "431");
  EXPECT_NE(r.text.find("\"too_large\""), std::string::npos) << r.text;
}

TEST(ServerHttpFraming, EncodingsTheServerDoesNotTakeAreRefusedUnread) {
  test::TempDbPath db("encodings");
  test::TestServer server(test::server_options(db.path));
  const int port = port_of(server.url());
  // A gzip body (its bytes do not matter: it is never inflated) and an unknown encoding: 415.
  for (const char* encoding : {"gzip", "zstd", "deflate, gzip"}) {
    SCOPED_TRACE(encoding);
    const auto r = send_and_read(port, std::string("POST /v1/sessions HTTP/1.1\r\nContent-Type: application/json\r\n"
                                                   "Content-Encoding: ") +
                                           encoding + "\r\nContent-Length: 4\r\n\r\nabcd");
    expect_one_closing_reply(r, "415");
  }
  // Transfer-Encoding in any case: chunked outside uploads is 411, others 501.
  const auto chunked = send_and_read(port,
                                     "POST /v1/sessions HTTP/1.1\r\nTransfer-Encoding: Chunked\r\n\r\n"
                                     "2\r\n{}\r\n0\r\n\r\n");
  expect_one_closing_reply(chunked, "411");
  const auto other =
      send_and_read(port, "POST /v1/sessions HTTP/1.1\r\nTransfer-Encoding: gzip, chunked\r\n\r\n0\r\n\r\n");
  expect_one_closing_reply(other, "501");
  // A POST with neither length nor encoding has no body: answered at once
  // (before: read until the connection closed).
  const auto start = Clock::now();
  const auto empty = send_and_read(
      port, "POST /v1/sessions HTTP/1.1\r\nContent-Type: application/json\r\nConnection: close\r\n\r\n", 2000ms);
  EXPECT_EQ(empty.text.substr(0, 12), "HTTP/1.1 400") << empty.text;
  EXPECT_NE(empty.text.find("needs a JSON body"), std::string::npos) << empty.text;
  EXPECT_LT(std::chrono::duration<double>(Clock::now() - start).count(), 1.0);
}

TEST(ServerHttpFraming, StalledHeadersAndBodiesGet408) {
  test::TempDbPath db("stall");
  ConnectionLimits limits;
  limits.header_timeout_s = 1.0;
  limits.body_timeout_s = 1.0;
  test::TestServer server(test::server_options(db.path), {}, limits);
  const int port = port_of(server.url());
  const auto headers = send_and_read(port, "GET /healthz HTTP/1.1\r\nX-Half: ", 4000ms);
  expect_one_closing_reply(headers, "408");
  EXPECT_NE(headers.text.find("\"timeout\""), std::string::npos) << headers.text;
  const auto body = send_and_read(port, "POST /v1/sessions HTTP/1.1\r\nContent-Length: 100\r\n\r\n{\"na", 4000ms);
  expect_one_closing_reply(body, "408");
}

TEST(ServerHttpFraming, KeptAliveRepliesSayKeepAliveAndErrorsAfterAWholeBodyKeepTheConnection) {
  test::TempDbPath db("keepalive");
  test::TestServer server(test::server_options(db.path));
  test::RawConnection c(port_of(server.url()));
  // A 400 to a body read whole leaves the connection in step: the next request on it is answered.
  ASSERT_TRUE(
      c.send("POST /v1/sessions HTTP/1.1\r\nContent-Type: application/json\r\nContent-Length: 2\r\n\r\n[]"
             "GET /healthz HTTP/1.1\r\n\r\n"));
  const auto r = c.read_until_closed(1500ms);
  EXPECT_EQ(test::occurrences(r.text, "HTTP/1.1 "), 2) << r.text;
  EXPECT_EQ(r.text.substr(0, 12), "HTTP/1.1 400") << r.text;
  EXPECT_EQ(r.text.find("Connection: close"), std::string::npos) << r.text;
  EXPECT_FALSE(r.closed);
}

TEST(ServerHttpFraming, SlowBodiesCannotStarveHealthChecks) {
  // 80 connections that send their headers, then one body byte a second (the
  // probe's attack): they held every HTTP thread, /healthz took 10-12 s.
  test::TempDbPath db("slow_bodies");
  ConnectionLimits limits;
  limits.max_waiting = 10;  // the server's for its default 20 threads
  test::TestServer server(test::server_options(db.path), {}, limits, 20);
  const int port = port_of(server.url());
  std::atomic<bool> stop{false};
  std::atomic<int> cut_off{0};
  std::vector<std::thread> slow;
  for (int i = 0; i < 80; ++i) {
    slow.emplace_back([&] {
      test::RawConnection c(port);
      if (!c.send("POST /v1/sessions HTTP/1.1\r\nContent-Type: application/json\r\nContent-Length: 1000\r\n\r\n"))
        return;
      while (!stop) {
        std::this_thread::sleep_for(1000ms);
        if (!c.send(" ")) {
          ++cut_off;
          break;
        }
      }
    });
  }
  std::this_thread::sleep_for(1500ms);
  std::vector<double> seconds;
  int answered = 0;
  for (const auto until = Clock::now() + 4s; Clock::now() < until;) {
    httplib::Client health(server.url());
    health.set_read_timeout(5s);
    const auto t0 = Clock::now();
    const auto r = health.Get("/healthz");
    seconds.push_back(std::chrono::duration<double>(Clock::now() - t0).count());
    if (r && r->status == 200) ++answered;
    std::this_thread::sleep_for(100ms);
  }
  stop = true;
  for (auto& t : slow) t.join();
  std::sort(seconds.begin(), seconds.end());
  const double median_s = seconds[seconds.size() / 2], worst_s = seconds.back();
  // The server's own count of what it closed: a slow client notices only at
  // its second byte after the close, up to 2 s later (on a loaded machine 49
  // had noticed when the test ended).
  const ConnectionStats stats = server.http().connection_stats();
  const std::uint64_t closed = stats.closed_for_room + stats.closed_slow;
  std::cout << "health checks: median " << median_s * 1e3 << " ms, worst " << worst_s * 1e3
            << " ms; slow bodies closed by the server: " << closed << " of 80 (" << cut_off.load()
            << " noticed by their clients)\n";
  EXPECT_EQ(answered, static_cast<int>(seconds.size()));
  EXPECT_GE(answered, 20);
  // Measured: 1 ms (before: 5 s timeouts). The bar is docs/server.md's 100 ms;
  // the worst of 40 gets room for a loaded machine.
  EXPECT_LT(median_s, 0.1);
  EXPECT_LT(worst_s, 0.25);
  // At least every one that neither the 20 threads nor the 10 places to wait
  // hold: 50. Measured 70 (all but the 10 waiting) on an idle machine, 61-71
  // with four busy loops beside the test (its 80 clients connect later there).
  EXPECT_GE(closed, 50u);
  EXPECT_GT(cut_off.load(), 0);
}

}  // namespace
}  // namespace orbatlas
