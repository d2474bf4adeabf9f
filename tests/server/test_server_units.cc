// The server's small parts with exact answers: map leases, request images,
// the latency histogram, pose JSON.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <future>

#include <opencv2/imgcodecs.hpp>
#include <prometheus/text_serializer.h>
#include <zlib.h>

#include "client/api/dataset_streamer.h"
#include "core/common/error.h"
#include "core/server/atlas_service.h"
#include "core/server/upload_jobs.h"
#include "server/http/http_api.h"
#include "server/http/image_decode.h"
#include "core/server/metrics_registry.h"
#include "core/server/live_session.h"
#include "core/server/map_leases.h"
#include "core/server/viewer_data.h"
#include "wire/pose_json.h"

namespace orbatlas {
namespace {

TEST(MapLeases, SessionsShareMapsTheMergingWorkerTakesAlone) {
  constexpr SessionId kWorker = 1000;
  MapLeases leases;
  leases.add_free(1);
  leases.add_free(2);
  // Session 10 tries maps 1 and 2 while relocalising and tracks in 2.
  EXPECT_TRUE(leases.claim(10, 1));
  EXPECT_TRUE(leases.claim(10, 2));
  EXPECT_TRUE(leases.claim(11, 2));  // mapping sessions share a map
  leases.settle(10, 2);
  EXPECT_EQ(leases.holders(2), (std::vector<SessionId>{10, 11}));
  EXPECT_TRUE(leases.holders(1).empty());  // the tentative claim was given back
  EXPECT_TRUE(leases.is_free(1));
  leases.settle(11, 1);  // 11 tracked in 1 after all: its claim on 2 goes back
  EXPECT_EQ(leases.holders(2), (std::vector<SessionId>{10}));
  // A map a session creates is unknown until its first settle, then others may enter it.
  EXPECT_FALSE(leases.claim(10, 7));
  leases.settle(11, 7);
  EXPECT_EQ(leases.held_by(11), (std::vector<MapId>{1, 7}));
  EXPECT_TRUE(leases.claim(10, 7));
  leases.settle(10, 7);
  EXPECT_EQ(leases.held_by(10), (std::vector<MapId>{2, 7}));  // held for good stays held
  // Lost (no map this frame): held maps stay held.
  leases.settle(11, std::nullopt);
  EXPECT_EQ(leases.held_by(11), (std::vector<MapId>{1, 7}));
  // The merging worker takes a map alone, and only a map nobody holds.
  EXPECT_FALSE(leases.claim_exclusive(kWorker, 7));
  EXPECT_FALSE(leases.claim_exclusive(kWorker, 1));
  leases.release_all(11);
  EXPECT_TRUE(leases.held_by(11).empty());
  EXPECT_TRUE(leases.claim_exclusive(kWorker, 1));
  EXPECT_FALSE(leases.claim(10, 1));  // no session enters it while the worker holds it
  EXPECT_FALSE(leases.share(7, 1));   // nor does a live merge go into it
  leases.release_all(kWorker);
  // A live merge of 7 into 1: 7's sessions hold 1 for good; 7 is forgotten.
  EXPECT_TRUE(leases.share(7, 1));
  leases.forget(7);
  EXPECT_EQ(leases.holders(1), (std::vector<SessionId>{10}));
  EXPECT_FALSE(leases.claim(11, 7));
  leases.release_all(10);
  EXPECT_TRUE(leases.is_free(1));
  EXPECT_TRUE(leases.is_free(2));
}

// The viewer's level-of-detail cap: every k-th point, k as small as the cap allows.
TEST(ViewerData, ThePointBufferKeepsEveryKthPointUnderTheCap) {
  MapPointCloud cloud;
  for (int i = 0; i < 10; ++i) cloud.points.emplace_back(i, 10 + i, 20 + i);
  const auto xs = [](const std::vector<float>& xyz) {
    std::vector<float> out;
    for (std::size_t i = 0; i < xyz.size(); i += 3) out.push_back(xyz[i]);
    return out;
  };
  EXPECT_EQ(xs(point_buffer(cloud, 10)), (std::vector<float>{0, 1, 2, 3, 4, 5, 6, 7, 8, 9}));  // all fit
  EXPECT_EQ(xs(point_buffer(cloud, 5)), (std::vector<float>{0, 2, 4, 6, 8}));
  EXPECT_EQ(xs(point_buffer(cloud, 4)), (std::vector<float>{0, 3, 6, 9}));
  EXPECT_EQ(xs(point_buffer(cloud, 1)), (std::vector<float>{0}));
  const std::vector<float> one = point_buffer(cloud, 4);
  EXPECT_EQ(std::vector<float>(one.begin() + 3, one.begin() + 6), (std::vector<float>{3, 13, 23}));  // x, y, z
  EXPECT_TRUE(point_buffer(MapPointCloud{}, 100).empty());
}

TEST(RequestImage, DecodesPngAndRawAndRefusesTheRest) {
  cv::Mat image(6, 8, CV_8UC1);
  for (int i = 0; i < image.rows * image.cols; ++i) image.data[i] = static_cast<unsigned char>(i * 5);
  std::vector<unsigned char> png;
  ASSERT_TRUE(cv::imencode(".png", image, png));
  const std::string png_bytes(png.begin(), png.end());
  const cv::Mat decoded = decode_request_image(png_bytes, std::nullopt, "left image");
  EXPECT_EQ(cv::norm(decoded, image, cv::NORM_INF), 0.0);
  const std::string raw(reinterpret_cast<const char*>(image.data), image.total());
  const cv::Mat from_raw = decode_request_image(raw, RawImageSize{8, 6}, "left image");
  EXPECT_EQ(cv::norm(from_raw, image, cv::NORM_INF), 0.0);
  // Raw pixels that begin like a bitmap file ("BM") are still raw pixels.
  std::string bm = raw;
  bm[0] = 'B';
  bm[1] = 'M';
  const cv::Mat from_bm = decode_request_image(bm, RawImageSize{8, 6}, "left image");
  EXPECT_EQ(from_bm.at<unsigned char>(0, 0), 'B');
  EXPECT_EQ(cv::norm(from_bm.colRange(2, 8), image.colRange(2, 8), cv::NORM_INF), 0.0);

  const auto message = [](auto&& f) {
    try {
      f();
    } catch (const DataError& e) {
      return std::string(e.what());
    }
    return std::string("no DataError");
  };
  EXPECT_NE(message([&] { decode_request_image(raw, std::nullopt, "left image"); }).find("'width' and 'height'"),
            std::string::npos);
  EXPECT_NE(message([&] {
              decode_request_image(raw, RawImageSize{8, 7}, "left image");
            }).find("48 bytes"),
            std::string::npos);
  EXPECT_NE(message([&] { decode_request_image(png_bytes.substr(0, 30), std::nullopt, "left image"); }).find("corrupt"),
            std::string::npos);
  EXPECT_NE(message([&] { decode_request_image("", std::nullopt, "right image"); }).find("right image is empty"),
            std::string::npos);
  // A header declaring 2^30 x 2^30 pixels: refused by its sides (before: its
  // area overflowed an int; found by fuzz_image_decode).
  std::string huge = png_bytes.substr(0, 24);
  for (const int at : {16, 20}) huge.replace(at, 4, std::string("\x40\x00\x00\x00", 4));
  EXPECT_NE(message([&] { decode_request_image(huge, std::nullopt, "left image"); }).find("at most 8192 pixels a side"),
            std::string::npos);
  cv::Mat deep(4, 4, CV_16UC1, cv::Scalar(1000));
  ASSERT_TRUE(cv::imencode(".png", deep, png));
  EXPECT_NE(
      message([&] { decode_request_image(std::string(png.begin(), png.end()), std::nullopt, "x"); }).find("8-bit"),
      std::string::npos);
}

// A PNG whose image data inflates to far more than its size needs (a
// 290 KB request with 300 MB of surplus IDAT cost 0.74 s of CPU): refused
// before decoding, after inflating at most its size's worth.
TEST(RequestImage, PngDataBeyondTheImageIsRefused) {
  const int width = 16, height = 16;
  const auto png_with_surplus = [&](std::size_t surplus) {
    std::string raw;
    for (int y = 0; y < height; ++y) raw += '\0' + std::string(width, static_cast<char>(y * 9));
    raw += std::string(surplus, '\0');
    uLongf packed_size = compressBound(raw.size());
    std::string packed(packed_size, '\0');
    EXPECT_EQ(compress(reinterpret_cast<Bytef*>(packed.data()), &packed_size,
                       reinterpret_cast<const Bytef*>(raw.data()), raw.size()),
              Z_OK);
    packed.resize(packed_size);
    const auto chunk = [](const std::string& type, const std::string& data) {
      std::string c;
      for (const std::uint32_t v : {static_cast<std::uint32_t>(data.size())})
        for (int shift = 24; shift >= 0; shift -= 8) c += static_cast<char>((v >> shift) & 0xff);
      const std::string body = type + data;
      const auto crc = static_cast<std::uint32_t>(crc32(0, reinterpret_cast<const Bytef*>(body.data()), body.size()));
      c += body;
      for (int shift = 24; shift >= 0; shift -= 8) c += static_cast<char>((crc >> shift) & 0xff);
      return c;
    };
    std::string ihdr;
    for (const std::uint32_t v : {static_cast<std::uint32_t>(width), static_cast<std::uint32_t>(height)})
      for (int shift = 24; shift >= 0; shift -= 8) ihdr += static_cast<char>((v >> shift) & 0xff);
    ihdr += std::string("\x08\x00\x00\x00\x00", 5);  // 8-bit grey, not interlaced
    return std::string("\x89PNG\r\n\x1a\n", 8) + chunk("IHDR", ihdr) + chunk("IDAT", packed) + chunk("IEND", "");
  };
  const cv::Mat plain = decode_request_image(png_with_surplus(0), std::nullopt, "left image");
  EXPECT_EQ(plain.size(), cv::Size(width, height));
  EXPECT_EQ(plain.at<unsigned char>(3, 5), 27);
  try {
    decode_request_image(png_with_surplus(8u << 20), std::nullopt, "left image");
    ADD_FAILURE() << "8 MiB of surplus image data was decoded";
  } catch (const DataError& e) {
    EXPECT_NE(std::string(e.what()).find("more image data than its 16x16 pixels need"), std::string::npos) << e.what();
  }
}

TEST(MetricsRegistry, CumulativeBucketsCountersAndLabelsInTheTextFormat) {
  MetricsRegistry metrics;
  prometheus::Histogram& h = metrics.histogram("x_seconds", "test", latency_buckets_seconds());
  for (const double ms : {0.5, 3.0, 3.0, 40.0, 5000.0}) h.Observe(ms / 1000.0);
  metrics.counter("x_total", "events").Increment(3);
  metrics.counter("y_total", "by reason", {{"reason", "slow"}}).Increment();
  metrics.counter("y_total", "by reason", {{"reason", "room"}});
  metrics.counter("y_total", "by reason", {{"reason", "slow"}}).Increment();  // the same series again
  metrics.gauge("z_bytes", "size").Set(151234567);
  const std::string text = prometheus::TextSerializer().Serialize(metrics.collect());
  EXPECT_NE(text.find("x_seconds_bucket{le=\"0.001\"} 1\n"), std::string::npos) << text;
  EXPECT_NE(text.find("x_seconds_bucket{le=\"0.005\"} 3\n"), std::string::npos) << text;
  EXPECT_NE(text.find("x_seconds_bucket{le=\"0.05\"} 4\n"), std::string::npos) << text;
  EXPECT_NE(text.find("x_seconds_bucket{le=\"+Inf\"} 5\n"), std::string::npos) << text;
  EXPECT_NE(text.find("x_seconds_count 5\n"), std::string::npos) << text;
  EXPECT_NE(text.find("x_seconds_sum 5.0465\n"), std::string::npos) << text;
  EXPECT_NE(text.find("# TYPE x_seconds histogram\n"), std::string::npos) << text;
  EXPECT_NE(text.find("# TYPE x_total counter\nx_total 3\n"), std::string::npos) << text;
  EXPECT_NE(text.find("y_total{reason=\"slow\"} 2\n"), std::string::npos) << text;
  EXPECT_NE(text.find("y_total{reason=\"room\"} 0\n"), std::string::npos) << text;
  EXPECT_NE(text.find("# TYPE z_bytes gauge\nz_bytes 151234567\n"), std::string::npos) << text;
}

// A session whose finish waits on something (the shared loop-closing thread, in
// the server) until the test lets it go.
class BlockingSlam final : public SessionSlam {
 public:
  explicit BlockingSlam(std::shared_future<void> release) : release_(std::move(release)) {}
  TrackResult process(TimestampNs, const cv::Mat&, const cv::Mat&) override { return {}; }
  void finish() override {
    finishing.set_value();
    release_.wait();
  }
  std::vector<FrameAnchor> anchors_from(std::size_t) const override { return {}; }
  std::optional<FrameAnchor> last_anchor() const override { return std::nullopt; }
  SlamStats stats() const override { return SlamStats(); }
  std::size_t worker_errors() const override { return 0; }
  std::promise<void> finishing;

 private:
  std::shared_future<void> release_;
};

// Asking a session for its state never waits for its finish. It did (the session
// mutex): with the service's mutex held by a health check waiting on a finishing
// session, and that finish waiting for the loop-closing thread, which recorded a
// live merge under the service's mutex, the server hung (found by reading the
// lock order; docs/architecture.md "Locks").
TEST(LiveSession, StateIsReadWithoutWaitingForAFinish) {
  std::promise<void> release;
  auto slam = std::make_unique<BlockingSlam>(release.get_future().share());
  std::future<void> finishing = slam->finishing.get_future();
  SessionInfo info;
  info.id = 7;
  LiveSession session(info, "test", std::move(slam));
  std::thread finisher([&] { session.finish(); });
  finishing.wait();  // finish() holds the session's mutex now
  auto state = std::async(std::launch::async, [&] { return session.state(); });
  const bool answered = state.wait_for(std::chrono::seconds(2)) == std::future_status::ready;
  release.set_value();
  finisher.join();
  ASSERT_TRUE(answered) << "state() waited for the finish";
  EXPECT_EQ(state.get(), SessionState::kActive);  // finishing, not finished yet
  EXPECT_EQ(session.state(), SessionState::kFinished);
}

TEST(PoseJson, RoundTrip) {
  const Pose3 pose(Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized())),
                   Eigen::Vector3d(1.5, -2, 0.25));
  const Pose3 back = pose_from_json(pose_to_json(pose));
  EXPECT_LT((back.t - pose.t).norm(), 1e-12);
  EXPECT_LT(rotation_distance(back, pose), 1e-12);
}

// The server's and the streaming client's options refuse values they cannot
// work with, naming the option (checked before anything starts).
template <class Options, class Change>
void expect_refused(Options options, Change change, const std::string& field) {
  change(options);
  try {
    options.check();
    ADD_FAILURE() << field << ": accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
  }
}

TEST(ServerOptions, CheckThemselves) {
  AtlasServiceOptions service;
  service.db = "/tmp/x.db";
  EXPECT_NO_THROW(service.check());
  expect_refused(
      service, [](auto& o) { o.db.clear(); }, "--db");
  expect_refused(
      service, [](auto& o) { o.max_live_sessions = 0; }, "max_live_sessions");
  expect_refused(
      service, [](auto& o) { o.slam.imu_input.stuck_samples = 1; }, "stuck_samples");
  expect_refused(
      service, [](auto& o) { o.loop_queue = 0; }, "loop_queue");
  expect_refused(
      service, [](auto& o) { o.merging.queue_capacity = 0; }, "queue_capacity");
  expect_refused(
      service, [](auto& o) { o.slam.new_map_after_failed_relocalizations = -1; },
      "new_map_after_failed_relocalizations");

  UploadJobOptions jobs;
  jobs.work_dir = "/tmp/work";
  EXPECT_NO_THROW(jobs.check());
  expect_refused(
      jobs, [](auto& o) { o.work_dir.clear(); }, "work folder");
  expect_refused(
      jobs, [](auto& o) { o.workers = 0; }, "workers");
  expect_refused(
      jobs, [](auto& o) { o.max_queued = 0; }, "max_queued");

  HttpApiOptions http;
  EXPECT_NO_THROW(http.check());
  expect_refused(
      http, [](auto& o) { o.max_body_bytes = 0; }, "max_body_bytes");
  expect_refused(
      http, [](auto& o) { o.max_upload_bytes = 0; }, "max_upload_bytes");

  StreamOptions stream;
  stream.dataset = "/tmp/MH_01";
  EXPECT_NO_THROW(stream.check());
  expect_refused(
      stream, [](auto& o) { o.rate = -1.0; }, "rate");
  expect_refused(
      stream, [](auto& o) { o.start_s = -2.0; }, "start_s");
  expect_refused(
      stream, [](auto& o) { o.duration_s = 0.0; }, "duration_s");
  expect_refused(
      stream, [](auto& o) { o.start_at_unix_s = std::nan(""); }, "start_at_unix_s");
  expect_refused(
      stream, [](auto& o) { o.repeat = 0; }, "repeat");
}

}  // namespace
}  // namespace orbatlas
