// Shared maps. Localisation sessions read, never lock: eight
// sessions (single camera and stereo, mode "localize") stream at once into one
// stored map over HTTP; each is tracked in that map's frame from its first
// recognised frame, and the map's rows in the database are unchanged. Mapping
// sessions share the map they are in: two devices flying through one place at
// once build one map together.
#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>
#include <sqlite3.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <algorithm>
#include <chrono>
#include <future>
#include <thread>
#include <string>
#include <vector>

#include "client/api/dataset_streamer.h"
#include "core/common/error.h"
#include "core/eval/evaluate.h"
#include "tests/support/server_test_fixture.h"
#include "tests/support/slam_test_clip.h"

namespace orbatlas {
namespace {

// Per table that holds maps: its row count and an FNV-1a digest of every row
// (blobs included byte for byte) in a fixed order; equal exactly when the
// stored maps are unchanged (up to a digest collision).
std::string map_rows(const std::filesystem::path& db) {
  sqlite3* handle = nullptr;
  EXPECT_EQ(sqlite3_open_v2(db.c_str(), &handle, SQLITE_OPEN_READONLY, nullptr), SQLITE_OK);
  std::string out;
  for (const char* table :
       {"maps", "keyframes", "map_points", "observations", "covisibility", "loop_edges", "culled_keyframes"}) {
    sqlite3_stmt* stmt = nullptr;
    // maps.saved_ns says when a map's row was last written, not what the map holds.
    const std::string columns = std::string(table) == "maps" ? "id" : "*";
    const std::string sql = "SELECT " + columns + " FROM " + table + " ORDER BY 1" + (columns == "*" ? ", 2" : "");
    EXPECT_EQ(sqlite3_prepare_v2(handle, sql.c_str(), -1, &stmt, nullptr), SQLITE_OK) << table;
    std::size_t rows = 0;
    std::uint64_t digest = 14695981039346656037ULL;
    const auto add = [&digest](const unsigned char* bytes, int n) {
      for (int i = 0; i < n; ++i) digest = (digest ^ bytes[i]) * 1099511628211ULL;
    };
    while (sqlite3_step(stmt) == SQLITE_ROW) {
      ++rows;
      for (int c = 0; c < sqlite3_column_count(stmt); ++c) {
        const auto* bytes = static_cast<const unsigned char*>(sqlite3_column_blob(stmt, c));
        const int n = sqlite3_column_bytes(stmt, c);
        const unsigned char separator[2] = {static_cast<unsigned char>(bytes ? 1 : 0), 0x1f};
        if (bytes) add(bytes, n);
        add(separator, 2);
      }
    }
    sqlite3_finalize(stmt);
    out += std::string(table) + ": " + std::to_string(rows) + " rows, digest " + std::to_string(digest) + "\n";
  }
  sqlite3_close(handle);
  return out;
}

// The body pose of `clip` at t_ns in the frame of a map whose origin is the
// body at the first frame of `origin` (all Machine Hall sequences share one world).
std::optional<Pose3> truth_in_map(const EurocDataset& clip, TimestampNs t_ns, const EurocDataset& origin) {
  Trajectory gt, origin_gt;
  for (const auto& s : clip.ground_truth) gt.push_back({s.t_ns, s.T_w_b});
  for (const auto& s : origin.ground_truth) origin_gt.push_back({s.t_ns, s.T_w_b});
  const auto pose = pose_at(gt, t_ns, 50'000'000);
  const auto first = pose_at(origin_gt, pair_stereo_frames(origin).front().t_ns, 50'000'000);
  if (!pose || !first) return std::nullopt;
  return first->inverse() * *pose;
}

// Position errors of `poses` (of a flight through `visit`) in the frame of a map
// built from `built`, no alignment fitted, accumulated into a running sum.
struct MapFrameError {
  double sum_sq = 0.0;
  std::size_t poses = 0;
  void add(const Trajectory& poses_in_map, const EurocDataset& visit, const EurocDataset& built) {
    for (const auto& p : poses_in_map) {
      const auto truth = truth_in_map(visit, p.t_ns, built);
      if (!truth) continue;
      sum_sq += (p.pose.t - truth->t).squaredNorm();
      ++poses;
    }
  }
  double rmse() const { return std::sqrt(sum_sq / static_cast<double>(std::max<std::size_t>(poses, 1))); }
};

// One device streaming `clip` at the camera rate on a connection of its own.
StreamReport stream_at_camera_rate(test::TestServer& server, const std::filesystem::path& clip, const std::string& name,
                                   const std::string& mode = {}, double start_s = 0.0) {
  ServerClient own(server.url());
  StreamOptions o = test::stream_options(clip);
  o.name = name;
  o.mode = mode;
  o.rate = 1.0;
  o.start_s = start_s;
  return stream_dataset(own, o);
}

TEST(SharedMaps, EightLocalisationSessionsShareAStoredMapAndChangeNothing) {
  const auto built = test::simulated_clip("MH_01", 40.0, 4.0);
  test::ClipCleanup built_cleanup{built};
  // Another flight through that place (no pose that built the map is re-rendered).
  const auto visit = test::simulated_clip("MH_02", 41.0, 3.0);
  test::ClipCleanup visit_cleanup{visit};
  test::TempDbPath db("shared_localize");
  {
    test::TestServer server(test::server_options(db.path));
    ServerClient client(server.url());
    const StreamReport report = stream_dataset(client, test::stream_options(built));
    ASSERT_EQ(report.tracked, report.frames);
  }
  const std::string rows_before = map_rows(db.path);

  // Enough HTTP threads for the eight streams and this test's own connection;
  // as orbatlas-server does, half of them may wait for a request. Between frames
  // the streams' keep-alive connections all wait: the guard closes the
  // longest-waiting, and the client sends the request again on a new one.
  ConnectionLimits limits;
  limits.max_waiting = 6;
  test::TestServer server(test::server_options(db.path), {}, limits, 12);
  ServerClient client(server.url());
  const nlohmann::json maps = client.get_json("/v1/maps");
  ASSERT_EQ(maps["maps"].size(), 1u);
  const std::uint64_t stored_map = maps["maps"][0]["id"];

  // A session in localize mode shows in the map's session list once it tracks there.
  {
    const auto frames = test::stereo_frames(visit);
    const nlohmann::json started = client.start_session("euroc/stereo", "probe", "", "localize");
    EXPECT_EQ(started["session"]["mode"], "localize");
    const std::uint64_t id = started["id"];
    const auto reply = client.post_frame(id, frames[5].t_ns, cv::imread(frames[5].left.string(), cv::IMREAD_GRAYSCALE),
                                         cv::imread(frames[5].right.string(), cv::IMREAD_GRAYSCALE));
    ASSERT_TRUE(reply["tracked"].get<bool>()) << reply.dump();
    const nlohmann::json map = client.get_json("/v1/maps/" + std::to_string(stored_map));
    EXPECT_EQ(map["sessions"], nlohmann::json::array({id})) << map.dump();
    EXPECT_FALSE(map.contains("live_session")) << "a localisation holds no lease";
    client.finish_session(id);
  }

  // Eight at once: four single-camera and four stereo localisation sessions,
  // starting at different moments of the visit.
  std::vector<std::future<StreamReport>> running;
  for (int i = 0; i < 8; ++i) {
    running.push_back(std::async(std::launch::async, [&, i] {
      ServerClient own(server.url());
      StreamOptions o = test::stream_options(visit);
      o.config = i % 2 == 0 ? "euroc/mono" : "euroc/stereo";
      o.mode = "localize";
      o.name = "localizer " + std::to_string(i);
      o.start_s = 0.25 * (i / 2);
      return stream_dataset(own, o);
    }));
  }
  std::vector<StreamReport> reports;
  for (auto& r : running) reports.push_back(r.get());

  const EurocDataset visit_data = test::stereo_dataset(visit);
  const EurocDataset built_data = test::stereo_dataset(built);
  MapFrameError error;
  for (std::size_t i = 0; i < reports.size(); ++i) {
    const StreamReport& r = reports[i];
    EXPECT_EQ(r.rejected, 0u) << "session " << i;
    EXPECT_EQ(r.keyframes, 0u) << "session " << i;
    // Tracked from the first recognised frame on (the first may be spent recognising).
    EXPECT_GE(r.tracked + 2, r.frames) << "session " << i;
    for (const auto m : r.reply_maps) EXPECT_EQ(m, stored_map) << "session " << i;
    // No alignment: the poses are in the stored map's frame, as the truth is.
    error.add(r.trajectory, visit_data, built_data);
  }
  ASSERT_GT(error.poses, 8u * 40u);
  const double rmse = error.rmse();
  EXPECT_LT(rmse, 0.011);  // measured 0.0055 m

  server.service().shutdown();  // the final checkpoint: what would change, is written
  EXPECT_EQ(map_rows(db.path), rows_before) << "a localisation changed the stored map";
}

// Both sessions' poses (in the map they share) against both flights' ground
// truth (one world), under one SE3 alignment.
double joint_ate(const std::vector<const StreamReport*>& reports, const std::vector<EurocDataset>& clips) {
  Trajectory estimate, truth;
  for (const StreamReport* r : reports) estimate.insert(estimate.end(), r->trajectory.begin(), r->trajectory.end());
  for (const EurocDataset& clip : clips)
    for (const auto& s : clip.ground_truth) truth.push_back({s.t_ns, s.T_w_b});
  const auto by_time = [](const StampedPose& a, const StampedPose& b) { return a.t_ns < b.t_ns; };
  std::sort(estimate.begin(), estimate.end(), by_time);
  std::sort(truth.begin(), truth.end(), by_time);
  return evaluate_trajectory(estimate, truth).ate.rmse;
}

TEST(SharedMaps, TwoMappingSessionsOverOnePlaceBuildOneMap) {
  // Two flights through the same part of the hall (the MH_02 window crosses
  // the MH_01 one), streamed at the camera rate; the second starts 1.5 s later.
  const auto first = test::simulated_clip("MH_01", 40.0, 4.0);
  test::ClipCleanup first_cleanup{first};
  const auto second = test::simulated_clip("MH_02", 41.0, 3.0);
  test::ClipCleanup second_cleanup{second};
  test::TempDbPath db("shared_mapping");
  AtlasServiceOptions options = test::server_options(db.path);
  options.merge_maps = true;  // live merging as the server does it by default; offline merging has nothing left
  // The clips' map is small (5 keyframes): the global BA at the first
  // session's end (--finish-refinement-wait, by default) applies to it from 2
  // keyframes on. Growth 0: none while they map (at 20 keyframes, never here).
  options.slam.loop.shared_map_refinement_min_keyframes = 2;
  options.slam.loop.shared_map_refinement_growth = 0.0;
  test::TestServer server(options);
  auto a = std::async(std::launch::async, [&] { return stream_at_camera_rate(server, first, "device a"); });
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  auto b = std::async(std::launch::async, [&] { return stream_at_camera_rate(server, second, "device b"); });
  const StreamReport ra = a.get();
  const StreamReport rb = b.get();

  for (const StreamReport* r : {&ra, &rb}) {
    EXPECT_EQ(r->rejected, 0u);
    EXPECT_GE(r->tracked + 1, r->frames);  // the first frame may be spent recognising the place
    EXPECT_GT(r->keyframes, 0u) << "both sessions add keyframes";
    ASSERT_TRUE(r->ate_rmse_m.has_value());
  }
  // While both were live, their last frames were tracked in one map, and every
  // pose of both ends in it: no merge after the fact was needed.
  ASSERT_FALSE(ra.reply_maps.empty());
  ASSERT_FALSE(rb.reply_maps.empty());
  const std::uint64_t shared = ra.reply_maps.back();
  EXPECT_EQ(rb.reply_maps.back(), shared);
  for (const StreamReport* r : {&ra, &rb})
    for (const auto m : r->trajectory_maps) EXPECT_EQ(m, shared);
  ServerClient client(server.url());
  EXPECT_EQ(client.get_json("/v1/maps")["maps"].size(), 1u);
  // The first session to end had the shared map adjusted in its finish.
  const std::string metrics = client.get_text("/metrics");
  const std::string end_line = "\norbatlas_stream_end_adjustments_total ";
  const auto end = metrics.find(end_line);
  ASSERT_NE(end, std::string::npos) << metrics;
  EXPECT_EQ(std::stod(metrics.substr(end + end_line.size())), 1.0);

  const double joint = joint_ate({&ra, &rb}, {test::stereo_dataset(first), test::stereo_dataset(second)});
  EXPECT_LT(joint, 2.0 * std::max(*ra.ate_rmse_m, *rb.ate_rmse_m));
  EXPECT_LT(joint, 0.0055);  // measured 0.0027 m (a alone 0.0009, b alone 0.0039)
}

// A map rewritten under a localisation: a mapping session starts a map of its
// own (start_in_stored_maps off), recognises the stored map while flying
// through it and is merged into it live, and loop closing runs a global BA of
// the joined map. A localisation session tracks in that map all along: every
// frame after its first is tracked, in that map, near the truth.
TEST(SharedMaps, ALocalisationKeepsTrackingWhileAMergeAndAGlobalAdjustmentRewriteItsMap) {
  const auto built = test::simulated_clip("MH_01", 40.0, 4.0);
  test::ClipCleanup built_cleanup{built};
  const auto visit = test::simulated_clip("MH_02", 40.0, 5.0);
  test::ClipCleanup visit_cleanup{visit};
  test::TempDbPath db("shared_rewrite");
  AtlasServiceOptions options = test::server_options(db.path);
  {
    test::TestServer server(options);
    ServerClient client(server.url());
    const StreamReport report = stream_dataset(client, test::stream_options(built));
    ASSERT_EQ(report.tracked, report.frames);
  }
  options.start_in_stored_maps = false;  // the mapping session starts apart and is merged live
  test::TestServer server(options);
  ServerClient client(server.url());
  const std::uint64_t stored_map = client.get_json("/v1/maps")["maps"][0]["id"];
  auto mapping = std::async(std::launch::async, [&] { return stream_at_camera_rate(server, visit, "map", "map"); });
  auto localize =
      std::async(std::launch::async, [&] { return stream_at_camera_rate(server, visit, "localize", "localize", 0.5); });
  mapping.get();
  const StreamReport rl = localize.get();

  const nlohmann::json merges = client.get_json("/v1/merges");
  ASSERT_GE(merges["live_merges"].size(), 1u) << merges.dump();
  const std::string metrics = client.get_text("/metrics");
  const std::string gba_line = "\norbatlas_global_adjustments_total ";
  const auto gba = metrics.find(gba_line);
  ASSERT_NE(gba, std::string::npos) << metrics;
  const double adjustments = std::stod(metrics.substr(gba + gba_line.size()));
  EXPECT_GE(adjustments, 1.0) << "a global BA followed the merge";

  EXPECT_EQ(rl.rejected, 0u);
  EXPECT_EQ(rl.keyframes, 0u);
  EXPECT_GE(rl.tracked + 1, rl.frames);  // the first frame may be spent recognising
  // Replies name the stored map, or the mapping session's map before it was
  // merged (a localisation may track in any map of its rig); afterwards every
  // frame is in the stored map.
  const std::uint64_t merged_map = merges["live_merges"][0]["source_map"];
  for (const auto m : rl.reply_maps) {
    EXPECT_TRUE(m == stored_map || m == merged_map) << m;
  }
  for (const auto m : rl.trajectory_maps) EXPECT_EQ(m, stored_map);
  const EurocDataset visit_data = test::stereo_dataset(visit);
  const EurocDataset built_data = test::stereo_dataset(built);
  MapFrameError error;
  error.add(rl.trajectory, visit_data, built_data);
  ASSERT_GT(error.poses, 80u);
  const double rmse = error.rmse();
  EXPECT_LT(rmse, 0.013);  // measured 0.0064 m
}

TEST(SharedMaps, TheModeIsCheckedAtStart) {
  test::TempDbPath db("shared_mode");
  test::TestServer server(test::server_options(db.path));
  ServerClient client(server.url());
  const auto refused = [&](const nlohmann::json& body) {
    const auto res = client.http().Post("/v1/sessions", body.dump(), "application/json");
    EXPECT_TRUE(res);
    return res ? std::make_pair(res->status, res->body) : std::make_pair(0, std::string());
  };
  const auto [bad_status, bad_body] = refused({{"config", "euroc/stereo"}, {"mode", "fly"}});
  EXPECT_EQ(bad_status, 400) << bad_body;
  EXPECT_NE(bad_body.find("map or localize"), std::string::npos) << bad_body;
  // A single camera with its IMU needs a config that has one.
  const auto [mono_status, mono_body] =
      refused({{"config", "euroc/mono"}, {"sensor", "mono_inertial"}, {"mode", "map"}});
  EXPECT_EQ(mono_status, 400) << mono_body;
  EXPECT_NE(mono_body.find("IMU"), std::string::npos) << mono_body;
  // Defaults: map for a stereo rig and a single camera of a single-camera
  // config (mono, mono_inertial); localize for the first camera of a stereo config.
  const nlohmann::json stereo = client.start_session("euroc/stereo", "s");
  EXPECT_EQ(stereo["session"]["mode"], "map");
  const nlohmann::json mono = client.start_session("euroc/mono", "m");
  EXPECT_EQ(mono["session"]["mode"], "map");
  const nlohmann::json left = client.start_session("euroc/stereo", "l", "mono");
  EXPECT_EQ(left["session"]["mode"], "localize");
  const nlohmann::json mono_inertial = client.start_session("euroc/mono_inertial", "mi");
  EXPECT_EQ(mono_inertial["session"]["mode"], "map");
  for (const auto* s : {&stereo, &mono, &left, &mono_inertial}) client.finish_session((*s)["id"]);
}

}  // namespace
}  // namespace orbatlas
