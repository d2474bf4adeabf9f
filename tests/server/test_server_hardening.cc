// What an outside probe of the server found, each as a test that
// fails on the code before its fix: ids and rows after a crash, one writer per
// database and per port, refusals before work (image headers, limits,
// timestamps, names), settings parsed in memory, idle sessions, HTTP details.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <fstream>
#include <thread>

#include "client/api/server_client.h"
#include "core/archive/tar_writer.h"
#include "core/common/data_paths.h"
#include "core/io/settings.h"
#include "core/persistence/atlas_checkpoint_writer.h"
#include "core/persistence/atlas_store.h"
#include "core/persistence/database_lock.h"
#include "server/http/image_decode.h"
#include "tests/support/server_test_fixture.h"
#include "tests/support/server_test_reply.h"

namespace orbatlas {
namespace {

using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

// One raw HTTP exchange on a fresh connection: sends `request`, returns what
// came back until the server closed or `wait` passed (status line first).
// Sends `request` in `pieces` equal parts, `pause` apart, then reads the reply
// (until its JSON body has come, or `wait` without a byte).
std::string raw_exchange(int port, const std::string& request, std::chrono::milliseconds wait, int pieces = 1,
                         std::chrono::milliseconds pause = std::chrono::milliseconds(0)) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(port));
  ::inet_pton(AF_INET, "127.0.0.1", &addr.sin_addr);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    ::close(fd);
    return "connect failed";
  }
  const std::size_t part = (request.size() + static_cast<std::size_t>(pieces) - 1) / static_cast<std::size_t>(pieces);
  for (std::size_t sent = 0; sent < request.size(); sent += part) {
    if (sent > 0) std::this_thread::sleep_for(pause);
    const std::size_t n = std::min(part, request.size() - sent);
    for (std::size_t done = 0; done < n;) {
      const ssize_t k = ::send(fd, request.data() + sent + done, n - done, MSG_NOSIGNAL);
      if (k <= 0) break;
      done += static_cast<std::size_t>(k);
    }
  }
  timeval tv{static_cast<time_t>(wait.count() / 1000), static_cast<suseconds_t>((wait.count() % 1000) * 1000)};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  std::string reply;
  char chunk[4096];
  for (ssize_t n; (n = ::recv(fd, chunk, sizeof chunk, 0)) > 0;) {
    reply.append(chunk, static_cast<std::size_t>(n));
    if (reply.find("\r\n\r\n") != std::string::npos && reply.find("}") != std::string::npos) break;
  }
  ::close(fd);
  return reply;
}

int port_of(const std::string& url) { return std::stoi(url.substr(url.rfind(':') + 1)); }

std::string settings_text(const std::string& config) {
  std::ifstream in(shipped_config_dir() / (config + ".yaml"));
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// A PNG header declaring a width x height 8-bit grey image, with no pixel data.
std::string png_header(std::uint32_t width, std::uint32_t height) {
  std::string b = "\x89PNG\r\n\x1a\n";
  b += std::string("\0\0\0\x0d", 4) + "IHDR";
  for (const std::uint32_t v : {width, height})
    for (int shift = 24; shift >= 0; shift -= 8) b += static_cast<char>((v >> shift) & 0xff);
  b += std::string("\x08\x00\x00\x00\x00", 5) + std::string(4, '\0');  // depth 8, grey; a CRC
  return b;
}

TEST(ServerHardening, AFrameNeverReferencesAKeyframeTheCheckpointDidNotStore) {
  // A session whose last frame is anchored to a keyframe the atlas does not
  // have (made after the snapshot, or never): the checkpoint leaves it out
  // (before: stored, later resolved through whatever got that id).
  test::TempDbPath db("dangling");
  Atlas atlas;
  const auto map = atlas.add_map(atlas.ids().next_map_id());
  const std::vector<FrameAnchor> frames = {{100, map->id(), 7777, Pose3()}};
  SessionInfo info;
  info.id = 1;
  info.name = "dangling";
  AtlasCheckpointWriter writer(
      atlas, AtlasStore::open(db.path, "test"),
      CheckpointSession{info,
                        [&](std::size_t first) { return first < frames.size() ? frames : std::vector<FrameAnchor>{}; },
                        /*record=*/{}});
  writer.checkpoint();
  EXPECT_EQ(writer.deferred_frames(), 1u);
  EXPECT_EQ(writer.dropped_frames(), 0u);
  // It is tried again by the next checkpoints, then left out for good.
  for (int i = 1; i < AtlasCheckpointWriter::kDeferrals; ++i) writer.checkpoint();
  EXPECT_EQ(writer.deferred_frames(), static_cast<std::size_t>(AtlasCheckpointWriter::kDeferrals));
  EXPECT_EQ(writer.dropped_frames(), 1u);
  writer.checkpoint();
  EXPECT_EQ(writer.deferred_frames(), static_cast<std::size_t>(AtlasCheckpointWriter::kDeferrals));
  AtlasStore store = AtlasStore::open(db.path, "test");
  EXPECT_TRUE(store.load_trajectory(1).empty()) << "a frame referencing keyframe 7777, which is stored nowhere";
  ASSERT_EQ(store.load_sessions().size(), 1u);
}

TEST(ServerHardening, OneServerPerDatabaseAndIdsSkipWhatACrashedOneHandedOut) {
  test::TempDbPath db("lock");
  std::uint64_t keyframe_id_before = 0;
  {
    AtlasService first(test::server_options(db.path));
    keyframe_id_before = first.atlas().ids().peek(IdKind::keyframe);
    try {
      AtlasService second(test::server_options(db.path));
      FAIL() << "a second server opened the same database";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("in use by another process"), std::string::npos) << e.what();
    }
  }
  {
    // A clean stop: the ids continue where they were.
    AtlasService again(test::server_options(db.path));
    EXPECT_EQ(again.atlas().ids().peek(IdKind::keyframe), keyframe_id_before);
  }
  { DatabaseLock crashed(db.path); }  // taken and dropped without mark_stopped(): what SIGKILL leaves
  AtlasService after_crash(test::server_options(db.path));
  EXPECT_GE(after_crash.atlas().ids().peek(IdKind::keyframe), keyframe_id_before + kKeyframeIdGapAfterCrash);
  EXPECT_GE(after_crash.atlas().ids().peek(IdKind::map_point), kMapPointIdGapAfterCrash);
  EXPECT_GE(after_crash.atlas().ids().peek(IdKind::map), kMapIdGapAfterCrash);
}

TEST(ServerHardening, ASessionIsStoredWhenCreatedSoItsIdIsNeverReused) {
  test::TempDbPath db("session_rows");
  AtlasServiceOptions options = test::server_options(db.path);
  options.checkpoints.every_keyframes = 0;  // no checkpoint until shutdown
  options.checkpoints.every_seconds = 0;
  AtlasService service(options);
  SessionRequest request;
  request.name = "short";
  request.settings.config = "euroc/stereo";
  const SessionId id = service.create_session(request);
  // Before any checkpoint, the database has the row (a crash now keeps the id taken).
  AtlasStore store = AtlasStore::open(db.path, service.vocabulary().hash());
  const auto stored = store.load_session(id);
  ASSERT_TRUE(stored.has_value());
  EXPECT_EQ(stored->name, "short");
}

TEST(ServerHardening, JobIdsSurviveARestartAndNoJobReadsAnotherOnesFiles) {
  // What a kill during an upload left: a job stored as running, and its
  // extracted folder with a previous client's recording.
  test::TempDbPath db("jobs");
  {
    AtlasService service(test::server_options(db.path));
    AtlasStore store = AtlasStore::open(db.path, service.vocabulary().hash());
    // Its session: two frames stored by its last checkpoint, which saw it running.
    SessionInfo session;
    session.id = 4;
    session.name = "theirs";
    store.save_session(session);
    store.save_trajectory(4, {FrameAnchor{100, 0, 1, Pose3()}, FrameAnchor{200, 0, 1, Pose3()}});
    SessionRecord record;
    record.frames = 3;
    record.tracked = 2;
    record.keyframes = 1;
    record.mode = "map";
    record.config = "euroc/stereo";
    store.save_session_record(4, record);
    StoredJob interrupted;
    interrupted.id = 1;
    interrupted.name = "theirs";
    interrupted.state = "running";
    interrupted.frames_total = 40;
    interrupted.session = 4;
    store.save_job(interrupted);
    // Another one killed before its session's first checkpoint.
    session.id = 5;
    store.save_session(session);
    interrupted.id = 2;
    interrupted.session = 5;
    store.save_job(interrupted);
  }
  const std::filesystem::path leftover = db.path.string() + ".work/job-3/mav0/cam0";
  std::filesystem::create_directories(leftover);
  { std::ofstream(leftover.parent_path() / "data.csv") << "#timestamp [ns],filename\n"; }

  test::TestServer server(test::server_options(db.path));
  ServerClient client(server.url());
  // Before: job ids restarted at 1 and nothing said what happened to the old job.
  const json old = client.get_json("/v1/jobs/1");
  EXPECT_EQ(old["state"], "failed");
  EXPECT_NE(old.value("error", "").find("interrupted"), std::string::npos) << old.dump();
  // What was kept, as the database has it (before: "stored in session N" also of a session holding none).
  EXPECT_NE(old.value("error", "").find("session 4 keeps the 2 tracked frames its last checkpoint stored"),
            std::string::npos)
      << old.dump();
  EXPECT_NE(
      client.get_json("/v1/jobs/2").value("error", "").find("nothing of it was stored (session 5 holds no frame)"),
      std::string::npos);
  // The session reports its last checkpoint's counts and that the server stopped under it.
  const json kept = client.get_json("/v1/sessions/4");
  EXPECT_EQ(kept["state"], "stored");
  EXPECT_EQ(kept["frames"], 3);
  EXPECT_EQ(kept["tracked"], 2);
  EXPECT_EQ(kept["keyframes"], 1);
  EXPECT_EQ(kept["mode"], "map");
  EXPECT_EQ(kept["config"], "euroc/stereo");
  EXPECT_EQ(kept["ended_by"], "interrupted");
  // A session of an older database (no record): its stored frames, nothing invented.
  const json older = client.get_json("/v1/sessions/5");
  EXPECT_EQ(older["frames"], 0);
  EXPECT_FALSE(older.contains("mode"));
  EXPECT_FALSE(older.contains("ended_by"));
  EXPECT_FALSE(std::filesystem::exists(leftover)) << "the earlier run's files were kept";
  // A tar without mav0/: before, the next job "finished" with the leftover folder's frames.
  std::string tar;
  {
    TarWriter writer([&](const char* d, std::size_t n) { tar.append(d, n); });
    writer.add_directory_entry("nothing-here/");
    writer.finish();
  }
  const auto reply = client.http().Post("/v1/uploads?name=mine", tar, "application/x-tar");
  ASSERT_TRUE(reply);
  ASSERT_EQ(reply->status, 202) << reply->body;
  const std::uint64_t job = json::parse(reply->body)["job"].get<std::uint64_t>();
  EXPECT_EQ(job, 3u);
  json status;
  for (const auto deadline = Clock::now() + std::chrono::seconds(30); Clock::now() < deadline;) {
    status = client.get_json("/v1/jobs/" + std::to_string(job));
    if (status["state"] == "failed" || status["state"] == "done") break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  EXPECT_EQ(status["state"], "failed") << status.dump();
  EXPECT_NE(status.value("error", "").find("no EuRoC ASL folder"), std::string::npos) << status.dump();
  EXPECT_EQ(status.value("error", "").find(db.path.string()), std::string::npos) << "a server path in the message";
}

TEST(ServerHardening, TwoServersCannotShareAPort) {
  test::TempDbPath db_a("port_a"), db_b("port_b");
  test::TestServer first(test::server_options(db_a.path));
  AtlasService service(test::server_options(db_b.path));
  httplib::Server second;
  install_http_api(second, service, {});
  // Before: SO_REUSEPORT let the second bind succeed and split the clients.
  EXPECT_FALSE(second.bind_to_port("127.0.0.1", port_of(first.url())));
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

TEST(ServerHardening, IdleSessionsAreFinishedAndFreeTheirSlot) {
  test::TempDbPath db("idle");
  AtlasServiceOptions options = test::server_options(db.path);
  options.idle_timeout_s = 0.3;
  options.max_live_sessions = 1;
  test::TestServer server(options);
  ServerClient client(server.url());
  const std::uint64_t abandoned = client.create_session("euroc/stereo", "abandoned");
  // Before: no timeout; the one slot stayed taken for good.
  const auto deadline = Clock::now() + std::chrono::seconds(20);
  json status;
  while (Clock::now() < deadline) {
    status = client.get_json("/v1/sessions/" + std::to_string(abandoned));
    if (status["state"] != "active") break;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  EXPECT_EQ(status["state"], "finished");
  EXPECT_EQ(status.value("ended_by", ""), "idle_timeout");
  EXPECT_NO_THROW(client.create_session("euroc/stereo", "next"));
  EXPECT_NE(client.get_text("/metrics").find("orbatlas_sessions_timed_out_total 1"), std::string::npos);
}

// The guard closes an idle keep-alive connection (a device between frames) to
// make room when more connections wait than it allows. The client sends the
// request again once on a new connection, so a device whose idle connection was
// cut goes on without an error: a GET, a session start (POST), an IMU batch and
// a finish after each cut all succeed.
TEST(ServerHardening, TheClientResendsOnceAfterTheServerClosedItsIdleConnection) {
  test::TempDbPath db("resend");
  ConnectionLimits limits;
  limits.max_waiting = 1;  // a second waiting connection crowds out the first
  test::TestServer server(test::server_options(db.path), {}, limits, 4);
  ServerClient client(server.url());
  EXPECT_EQ(client.get_json("/healthz")["status"], "ok");
  // Another device connects and waits: the client's idle connection is closed for room.
  std::size_t cuts = 0;
  const auto crowd_out = [&] {
    ServerClient other(server.url());
    // The closure is counted as the other connection starts waiting: look a few times.
    for (int attempt = 0; attempt < 50; ++attempt) {
      const std::string metrics = other.get_text("/metrics");
      const std::string key = "orbatlas_http_connections_closed_total{reason=\"room\"} ";
      const auto at = metrics.find(key);
      const std::size_t now = at == std::string::npos ? 0 : std::stoul(metrics.substr(at + key.size()));
      if (now > cuts) {
        cuts = now;
        return true;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return false;
  };
  // A GET on the closed connection is resent, whichever way the closure shows
  // (the request cannot be written, or its reply cannot be read).
  for (int cut = 0; cut < 3; ++cut) {
    EXPECT_TRUE(crowd_out());
    EXPECT_EQ(client.get_json("/healthz")["status"], "ok");
  }
  // A POST is resent only when it could not be written: when the server's FIN
  // reached the client before it wrote, the write succeeds and the reply cannot
  // be read, and the client cannot know whether the server took it (not
  // resent; which of the two happens is the kernel's timing, so the POSTs here
  // go after a GET opened a fresh connection).
  const std::uint64_t id = client.create_session("euroc/stereo", "after a pause");
  EXPECT_EQ(client.post_imu(id, {ImuSample{1, Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, 9.81)}})["accepted"], 1);
  EXPECT_TRUE(crowd_out());
  EXPECT_EQ(client.get_json("/v1/sessions/" + std::to_string(id))["state"], "active");
  EXPECT_EQ(client.finish_session(id).at("state"), "finished");
}

// A device streaming frames keeps one connection: httplib's default closed it
// every 5 requests, four reconnections a second for a live session, each with
// a receive window that starts small again (docs/server.md, "Connections").
TEST(ServerHardening, OneKeptAliveConnectionCarriesManyRequests) {
  test::TempDbPath db("keep_alive");
  test::TestServer server(test::server_options(db.path));
  ServerClient client(server.url());
  for (int i = 0; i < 60; ++i) ASSERT_EQ(client.get_json("/healthz")["status"], "ok");
  const auto connections = [&] { return server.http().connection_stats().connections; };
  EXPECT_EQ(connections(), 1u);
  // The bound still holds when set: three connections for 60 requests at 25 each.
  test::TempDbPath db2("keep_alive_bound");
  ConnectionLimits limits;
  limits.keep_alive_requests = 25;
  test::TestServer bounded(test::server_options(db2.path), {}, limits, 4);
  ServerClient bounded_client(bounded.url());
  for (int i = 0; i < 60; ++i) ASSERT_EQ(bounded_client.get_json("/healthz")["status"], "ok");
  EXPECT_EQ(bounded.http().connection_stats().connections, 3u);
}

TEST(ServerHardening, SlowClientsCannotStarveHealthChecks) {
  // Ten connections sending one header line every 0.5 s (before: they held all
  // 8 HTTP threads, and /healthz timed out for as long as they went on).
  test::TempDbPath db("slow");
  ConnectionLimits limits;
  limits.header_timeout_s = 2.0;
  limits.max_waiting = 4;
  test::TestServer server(test::server_options(db.path), {}, limits, 8);
  const int port = port_of(server.url());
  std::atomic<bool> stop{false};
  std::atomic<int> cut_off{0};
  std::vector<std::thread> slow;
  for (int i = 0; i < 10; ++i) {
    slow.emplace_back([&] {
      const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
      sockaddr_in addr{};
      addr.sin_family = AF_INET;
      addr.sin_port = htons(static_cast<std::uint16_t>(port));
      ::inet_pton(AF_INET, "127.0.0.1", &addr.sin_addr);
      if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0) {
        ::send(fd, "GET /healthz HTTP/1.1\r\n", 23, MSG_NOSIGNAL);
        while (!stop) {
          std::this_thread::sleep_for(std::chrono::milliseconds(500));
          if (::send(fd, "X-Slow: 1\r\n", 11, MSG_NOSIGNAL) < 0) {
            ++cut_off;
            break;
          }
        }
      }
      ::close(fd);
    });
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  // Health checks during the next 4 s all answer, and quickly.
  double worst_s = 0.0;
  int answered = 0;
  for (const auto until = Clock::now() + std::chrono::seconds(4); Clock::now() < until;) {
    httplib::Client health(server.url());
    health.set_read_timeout(std::chrono::seconds(5));
    const auto t0 = Clock::now();
    const auto r = health.Get("/healthz");
    worst_s = std::max(worst_s, std::chrono::duration<double>(Clock::now() - t0).count());
    if (r && r->status == 200) ++answered;
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  stop = true;
  for (auto& t : slow) t.join();
  std::printf("slow clients: %d health checks answered, the slowest in %.3f s; %d of 10 slow connections cut off\n",
              answered, worst_s, cut_off.load());
  EXPECT_GE(answered, 10);
  EXPECT_LT(worst_s, 0.5);
  EXPECT_GT(cut_off.load(), 0);  // past their header deadline, or to make room
  const std::string metrics = ServerClient(server.url()).get_text("/metrics");
  EXPECT_NE(metrics.find("orbatlas_http_connections_closed_total{reason=\"slow\"}"), std::string::npos);
}

// A large body that arrives in pieces with pauses between them is read whole:
// the connection's reads take what the socket holds without waiting, and wait
// (with the body's deadline) only when it holds nothing.
TEST(ServerHardening, ALargeBodyArrivingInPiecesIsReadWhole) {
  test::TempDbPath db("pieces");
  test::TestServer server(test::server_options(db.path));
  const int port = port_of(server.url());
  std::string yaml = settings_text("euroc/stereo");
  yaml += "\n# " + std::string(600 * 1024, 'x') + "\n";  // 600 KiB: more than one read's buffer
  const std::string body = nlohmann::json{{"name", "pieces"}, {"settings_yaml", yaml}}.dump();
  const std::string request =
      "POST /v1/sessions HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\n"
      "Content-Length: " +
      std::to_string(body.size()) + "\r\n\r\n" + body;
  const std::string reply = raw_exchange(port, request, std::chrono::seconds(10), 7, std::chrono::milliseconds(150));
  EXPECT_EQ(reply.substr(0, 12), "HTTP/1.1 201") << reply.substr(0, 400);
  EXPECT_NE(reply.find("\"id\""), std::string::npos) << reply.substr(0, 400);
}

TEST(ServerHardening, HttpDetails) {
  test::TempDbPath db("http");
  const auto configs = std::filesystem::temp_directory_path() / ("orbatlas_test_configs_" + std::to_string(::getpid()));
  std::filesystem::create_directories(configs);
  { std::ofstream(configs / "broken.yaml") << "%YAML:1.0\nCamera1.fx: -3\n"; }
  AtlasServiceOptions options = test::server_options(db.path);
  options.config_dir = configs;
  HttpApiOptions api;
  api.max_upload_bytes = 1u << 20;
  test::TestServer server(options, api);
  const int port = port_of(server.url());
  ServerClient client(server.url());

  // An upload over the limit: 413 at once, from its Content-Length (before: 400
  // after a 5 s read timeout).
  const auto start = Clock::now();
  const std::string big =
      raw_exchange(port, "POST /v1/uploads?name=big HTTP/1.1\r\nHost: x\r\nContent-Length: 99999999999\r\n\r\n",
                   std::chrono::seconds(10));
  EXPECT_EQ(big.substr(0, 12), "HTTP/1.1 413") << big;
  EXPECT_LT(std::chrono::duration<double>(Clock::now() - start).count(), 2.0);
  // Two Content-Length headers (request smuggling): 400.
  const std::string twice =
      raw_exchange(port, "POST /v1/sessions HTTP/1.1\r\nHost: x\r\nContent-Length: 2\r\nContent-Length: 40\r\n\r\n{}",
                   std::chrono::seconds(5));
  EXPECT_EQ(twice.substr(0, 12), "HTTP/1.1 400") << twice;
  EXPECT_NE(twice.find("more than one Content-Length"), std::string::npos) << twice;
  // A known route with another method: 405 with Allow; the undocumented
  // code "http_error" is gone (a malformed request is bad_request).
  EXPECT_REPLY(client.http().Put("/v1/sessions", "{}", "application/json"), 405, "method_not_allowed");
  const std::string garbage = raw_exchange(port, "NONSENSE\r\n\r\n", std::chrono::seconds(5));
  EXPECT_EQ(garbage.find("http_error"), std::string::npos) << garbage;
  // A form-urlencoded JSON body (curl -d) over httplib's 8 kB limit says what to do.
  const auto form =
      client.http().Post("/v1/sessions/1/imu", std::string(9000, 'x'), "application/x-www-form-urlencoded");
  ASSERT_TRUE(form);
  EXPECT_EQ(form->status, 413);
  EXPECT_NE(form->body.find("application/json"), std::string::npos) << form->body;
  // Error messages name configs, never the server's files.
  const auto broken = client.http().Post("/v1/sessions", R"({"config": "broken"})", "application/json");
  ASSERT_TRUE(broken);
  EXPECT_EQ(broken->status, 400);
  EXPECT_EQ(broken->body.find(configs.string()), std::string::npos) << broken->body;
  EXPECT_NE(broken->body.find("config 'broken'"), std::string::npos) << broken->body;
  std::filesystem::remove_all(configs);
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
