// HTTPS: the server with a throwaway certificate (made by Debian's
// `openssl`), a stream, an upload and a localisation over it end to end, and
// what a client that does not trust it, or does not speak TLS, gets.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <thread>

#include <opencv2/imgcodecs.hpp>

#include "client/api/dataset_streamer.h"
#include "client/api/server_client.h"
#include "core/common/error.h"
#include "core/io/euroc_reader.h"
#include "server/http/tls_context.h"
#include "tests/support/raw_http.h"
#include "tests/support/slam_test_clip.h"
#include "tests/support/server_test_fixture.h"  // last: it includes <httplib.h>

namespace orbatlas {
namespace {

using json = nlohmann::json;
using namespace std::chrono_literals;

// A self-signed certificate for 127.0.0.1 and its key, in a folder of their own.
struct ThrowawayCertificate {
  std::string tag;
  std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("orbatlas_test_tls_" + std::to_string(::getpid()) + "_" + tag);
  std::filesystem::path cert = dir / "cert.pem", key = dir / "key.pem";
  explicit ThrowawayCertificate(std::string name) : tag(std::move(name)) {
    std::filesystem::create_directories(dir);
    const std::string command =
        "openssl req -x509 -newkey rsa:2048 -nodes -days 2 -subj /CN=127.0.0.1 "
        "-addext subjectAltName=IP:127.0.0.1 -keyout " +
        key.string() + " -out " + cert.string() + " >/dev/null 2>&1";
    ok = std::system(command.c_str()) == 0 && std::filesystem::is_regular_file(cert);
  }
  ~ThrowawayCertificate() { std::filesystem::remove_all(dir); }
  bool ok = false;
};

int port_of(const std::string& url) { return std::stoi(url.substr(url.rfind(':') + 1)); }

TEST(ServerTls, AStreamAnUploadAndALocalisationWorkOverHttps) {
  ThrowawayCertificate certificate("e2e");
  ASSERT_TRUE(certificate.ok) << "openssl could not make a certificate (Debian's openssl package)";
  const auto clip = test::simulated_clip("MH_01", 40.0, 4.0);
  test::ClipCleanup cleanup{clip};
  test::TempDbPath db("tls");
  HttpApiOptions api;
  api.token = "s3cret";
  test::TestServer server(test::server_options(db.path), api, {}, 8,
                          std::make_shared<const TlsContext>(certificate.cert, certificate.key));
  ASSERT_EQ(server.url().rfind("https://", 0), 0u);
  ServerClient client(server.url(), "s3cret", certificate.cert.string());

  const StreamReport streamed = stream_dataset(client, test::stream_options(clip));
  EXPECT_EQ(streamed.frames, 81u);
  EXPECT_EQ(streamed.tracked, streamed.frames);
  ASSERT_TRUE(streamed.ate_rmse_m.has_value());
  EXPECT_LT(*streamed.ate_rmse_m, 0.05);

  const std::uint64_t job = client.upload(clip, "euroc/stereo", "over TLS");
  json status;
  for (int i = 0; i < 600; ++i) {
    status = client.get_json("/v1/jobs/" + std::to_string(job));
    if (status["state"] == "done" || status["state"] == "failed") break;
    std::this_thread::sleep_for(100ms);
  }
  EXPECT_EQ(status["state"], "done") << status.dump();

  const EurocDataset dataset = read_euroc_dataset(clip);
  const auto pairs = pair_stereo_frames(dataset);
  const cv::Mat left = cv::imread(pairs[40].left.string(), cv::IMREAD_GRAYSCALE);
  const cv::Mat right = cv::imread(pairs[40].right.string(), cv::IMREAD_GRAYSCALE);
  const json localised = client.localize("euroc/stereo", left, right);
  EXPECT_TRUE(localised["recognised"].get<bool>()) << localised.dump();
}

TEST(ServerTls, ClientsThatDoNotTrustOrSpeakTlsGetNothingAndTheServerGoesOn) {
  ThrowawayCertificate certificate("refused");
  ASSERT_TRUE(certificate.ok) << "openssl could not make a certificate (Debian's openssl package)";
  test::TempDbPath db("tls_refused");
  ConnectionLimits limits;
  limits.header_timeout_s = 1.0;
  test::TestServer server(test::server_options(db.path), {}, limits, 8,
                          std::make_shared<const TlsContext>(certificate.cert, certificate.key));
  // Not trusted (the system's authorities do not know it): no connection, no request.
  ServerClient untrusting(server.url());
  EXPECT_THROW(untrusting.get_json("/v1/sessions"), Error);
  // Plain HTTP on the TLS port: closed without a reply.
  test::RawConnection plain(port_of(server.url()));
  ASSERT_TRUE(plain.connected());
  plain.send("GET /healthz HTTP/1.1\r\n\r\n");
  const auto r = plain.read_until_closed(3000ms);
  EXPECT_TRUE(r.closed);
  EXPECT_EQ(r.text.find("HTTP/1.1 200"), std::string::npos);
  // A client that connects and says nothing is dropped after the header timeout.
  test::RawConnection silent(port_of(server.url()));
  EXPECT_TRUE(silent.read_until_closed(3000ms).closed);
  ServerClient trusting(server.url(), "", certificate.cert.string());
  EXPECT_EQ(trusting.get_json("/healthz")["status"], "ok");
  // A certificate and key that do not belong together: refused at start.
  ThrowawayCertificate other("other");
  std::filesystem::rename(other.key, certificate.dir / "other_key.pem");
  EXPECT_THROW(TlsContext(certificate.cert, certificate.dir / "other_key.pem"), Error);
}

}  // namespace
}  // namespace orbatlas
