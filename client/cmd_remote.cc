// Commands that talk to a running map server (docs/api.md): `orbatlas stream`
// (a recorded sequence as a live session), `orbatlas upload` (a recording run by
// the server), `orbatlas sessions|maps|jobs|merges`, `orbatlas trajectory`.
#include <chrono>
#include <cstdio>
#include <fstream>
#include <thread>
#include <memory>
#include <set>
#include <string>

#include "client/api/dataset_streamer.h"
#include "client/bag_options.h"
#include "client/commands.h"
#include "core/common/error.h"
#include "core/common/progress.h"
#include "core/io/euroc_trajectory.h"
#include "core/io/tum_trajectory.h"
#include "core/slam/slam_stats.h"
#include "wire/stats_json.h"

namespace orbatlas::cli {
namespace {

struct ServerArgs {
  std::string server = "http://127.0.0.1:8080";
  std::string token, ca;
};

void add_server_options(CLI::App* cmd, ServerArgs& args) {
  cmd->add_option("--server", args.server, "Map server URL")->envname("ORBATLAS_SERVER")->capture_default_str();
  cmd->add_option("--token", args.token, "Bearer token of the server")->envname("ORBATLAS_TOKEN");
  cmd->add_option("--ca", args.ca, "With an https:// server: the certificate authority (PEM) to check it against")
      ->envname("ORBATLAS_CA");
}

struct StreamArgs {
  ServerArgs server;
  StreamOptions stream;
  std::string dataset, encoding = "raw", out_trajectory, out_live_trajectory, stats, frame_log, format = "tum";
  double duration_s = 0.0;
  BagArgs bag;
};

// One line per frame answered: several clients' logs line up on sent_unix_us.
void write_frame_log(const std::string& path, const StreamReport& r) {
  std::ofstream out(path);
  out << "t_ns,sent_unix_us,round_trip_ms,server_ms,tracking_ms,late,skipped,keyframe,local_keyframes,local_points,"
         "maps_wait_ms,maps_busy\n";
  for (const StreamReport::FrameTiming& f : r.frame_timings)
    out << f.t_ns << ',' << f.sent_unix_us << ',' << f.round_trip_ms << ',' << f.server_ms << ',' << f.tracking_ms
        << ',' << f.late << ',' << f.skipped << ',' << f.keyframe << ',' << f.local_keyframes << ',' << f.local_points
        << ',' << f.maps_wait_ms << ',' << f.maps_busy << '\n';
  if (!out) throw Error("cannot write the frame log " + path);
}

nlohmann::json stream_json(const StreamReport& r) {
  std::vector<double> server_overhead, client_overhead;
  for (std::size_t i = 0; i < r.tracking_ms.size(); ++i) {
    server_overhead.push_back(r.server_ms[i] - r.tracking_ms[i]);
    client_overhead.push_back(r.round_trip_ms[i] - r.tracking_ms[i]);
  }
  nlohmann::json j = {{"session", r.session},
                      {"frames", r.frames},
                      {"tracked", r.tracked},
                      {"rejected", r.rejected},
                      {"keyframes", r.keyframes},
                      {"late_frames", r.late_frames},
                      {"skipped_frames", r.skipped_frames},
                      {"maps_busy_frames", r.maps_busy_frames},
                      {"imu_samples", r.imu_samples},
                      {"wall_s", r.wall_s},
                      {"finish_ms", r.finish_ms},
                      {"fps", r.fps()},
                      {"tracking_ms", to_json_summary(r.tracking_ms)},
                      {"server_ms", to_json_summary(r.server_ms)},
                      {"round_trip_ms", to_json_summary(r.round_trip_ms)},
                      {"server_overhead_ms", to_json_summary(server_overhead)},
                      {"client_overhead_ms", to_json_summary(client_overhead)}};
  std::set<std::uint64_t> maps(r.trajectory_maps.begin(), r.trajectory_maps.end());
  j["maps"] = maps;
  if (r.finish_status.contains("slam") && r.finish_status["slam"].contains("imu_initialized_at_s")) {
    j["imu_initialized_at_s"] = r.finish_status["slam"]["imu_initialized_at_s"];
    j["imu_bias"] = r.finish_status["slam"]["imu_bias"];
  }
  if (r.finish_status.contains("slam") && r.finish_status["slam"].contains("mapping_wait_ms")) {
    j["mapping_wait_ms"] = r.finish_status["slam"]["mapping_wait_ms"];
    j["mapping_waits_cut"] = r.finish_status["slam"]["mapping_waits_cut"];
  }
  if (r.ate_rmse_m) {
    j["ate_rmse_m"] = *r.ate_rmse_m;
    j["ate_align"] = r.ate_sim3 ? "sim3" : "se3";
    j["ate_poses"] = r.ate_poses;
  }
  // What the replies carried: the poses a device steers by.
  j["live_poses"] = r.live_trajectory.size();
  j["live_fraction"] = r.live_fraction();
  j["live_jumps_m"] = to_json_summary(r.live_jumps_m);
  if (r.live_ate_rmse_m) {
    j["live_ate_rmse_m"] = *r.live_ate_rmse_m;
    j["live_ate_poses"] = r.live_ate_poses;
  }
  return j;
}

void print_stream_summary(const nlohmann::json& j) {
  const auto p = [&](const char* key, const char* q) { return j[key][q].get<double>(); };
  std::printf("session %llu: %zu frames sent, %zu tracked, %zu refused, %zu keyframes, %.1f frames/s\n",
              static_cast<unsigned long long>(j["session"].get<std::uint64_t>()), j["frames"].get<std::size_t>(),
              j["tracked"].get<std::size_t>(), j["rejected"].get<std::size_t>(), j["keyframes"].get<std::size_t>(),
              j["fps"].get<double>());
  if (j["frames"].get<std::size_t>() > 0) {
    std::printf(
        "  tracking p50 %.1f / p95 %.1f ms; round trip p50 %.1f / p95 %.1f ms; late frames %zu; skipped frames %zu; "
        "maps busy %zu\n",
        p("tracking_ms", "p50"), p("tracking_ms", "p95"), p("round_trip_ms", "p50"), p("round_trip_ms", "p95"),
        j["late_frames"].get<std::size_t>(), j["skipped_frames"].get<std::size_t>(),
        j["maps_busy_frames"].get<std::size_t>());
    std::printf(
        "  added by the server (request - tracking) p50 %.2f / p95 %.2f ms; by HTTP and the client p50 %.2f ms\n",
        p("server_overhead_ms", "p50"), p("server_overhead_ms", "p95"), p("client_overhead_ms", "p50"));
  }
  std::string maps;
  for (const auto& m : j["maps"]) maps += (maps.empty() ? "" : ", ") + std::to_string(m.get<std::uint64_t>());
  std::printf("  maps: %s\n", maps.empty() ? "none" : maps.c_str());
  if (j.contains("ate_rmse_m"))
    std::printf("  ATE %.4f m (RMSE over %zu poses, %s to the ground truth)\n", j["ate_rmse_m"].get<double>(),
                j.value("ate_poses", std::size_t{0}),
                j.value("ate_align", "se3") == "sim3" ? "the camera's, Sim3-aligned" : "SE3-aligned");
  std::printf("  live poses: %zu (%.1f%% of the frames sent)", j["live_poses"].get<std::size_t>(),
              100.0 * j["live_fraction"].get<double>());
  if (j.contains("live_ate_rmse_m")) std::printf(", live ATE %.4f m", j["live_ate_rmse_m"].get<double>());
  const auto& jumps = j["live_jumps_m"];
  if (jumps["count"].get<std::size_t>() > 0)
    std::printf("; %zu jumps at corrections, p50 %.3f / max %.3f m", jumps["count"].get<std::size_t>(),
                jumps["p50"].get<double>(), jumps["max"].get<double>());
  std::printf("\n");
}

void register_stream(CLI::App& app) {
  auto args = std::make_shared<StreamArgs>();
  auto* cmd = app.add_subcommand("stream", "Stream a recorded sequence to a map server as a live session");
  add_server_options(cmd, args->server);
  cmd->add_option("--dataset", args->dataset,
                  "Folder holding mav0/ (cam0, cam1), a KITTI odometry sequence (image_0/, image_1/, times.txt, "
                  "calib.txt), or an RGB-D recording in the TUM layout (rgb.txt, depth.txt) for an rgbd config")
      ->check(CLI::ExistingDirectory);
  add_bag_options(cmd, args->bag, false);
  cmd->add_option("--config", args->stream.config,
                  "Settings: a config name the server knows, or a settings file here (sent as its text); default "
                  "euroc/stereo, or a KITTI sequence's own from its calib.txt");
  cmd->add_option("--sensor", args->stream.sensor,
                  "stereo or mono (default: the config's Sensor.type); mono sends the left images and localises in the "
                  "stored maps");
  cmd->add_option("--mode", args->stream.mode,
                  "map (track and add to a map; stereo only) or localize (track in the stored maps, change nothing); "
                  "default: map for stereo, localize for mono")
      ->check(CLI::IsMember({"map", "localize"}));
  cmd->add_option("--name", args->stream.name, "Session name (default: the dataset folder's name)");
  cmd->add_option("--rate", args->stream.rate,
                  "1: at the sensor rate, 2: twice as fast, 0: as fast as the server answers")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--max-lag", args->stream.max_lag_s,
                  "A real-time session: the server skips the frames that arrive more than this many seconds behind "
                  "the sensor's clock (counted as skipped frames) instead of falling further behind")
      ->check(CLI::PositiveNumber);
  cmd->add_flag("--preload", args->stream.preload,
                "Read and decode every image before the first frame is sent (memory: the clip's raw pixels, held in an "
                "in-memory file), so that the client's decoding does not compete with a server on the same machine "
                "while it streams");
  cmd->add_option("--repeat", args->stream.repeat,
                  "Stream the clip this many times in one session, each pass's timestamps after the last's (a long "
                  "run from a short clip; sessions without an IMU)")
      ->capture_default_str()
      ->check(CLI::Range(1, 1000));
  cmd->add_option("--start-at", args->stream.start_at_unix_s,
                  "Wait until this wall-clock time (seconds since the Unix epoch) before the first frame, after any "
                  "--preload: clients started together begin together");
  cmd->add_option("--encoding", args->encoding, "Images as 'raw' 8-bit pixels or 'png'")
      ->capture_default_str()
      ->check(CLI::IsMember({"raw", "png"}));
  cmd->add_option("--start", args->stream.start_s, "Seconds of the sequence to skip")->capture_default_str();
  cmd->add_option("--duration", args->duration_s, "Seconds to stream (default: to the end)");
  cmd->add_option("--out-trajectory", args->out_trajectory, "Write the session's final trajectory here (--format)");
  cmd->add_option("--out-live-trajectory", args->out_live_trajectory,
                  "Write the poses the replies carried here, as they were answered (--format; '# map' lines)");
  cmd->add_option("--format", args->format,
                  "Trajectory file format: tum (t tx ty tz qx qy qz qw, seconds) or euroc (the csv of EuRoC's ground "
                  "truth: ns,px,py,pz,qw,qx,qy,qz; what evo_traj euroc reads)")
      ->capture_default_str()
      ->check(CLI::IsMember({"tum", "euroc"}));
  cmd->add_option("--stats", args->stats, "Write the figures as JSON here");
  cmd->add_option("--frame-log", args->frame_log,
                  "Write one CSV line per frame here: when it was sent (Unix us), round trip, server and tracking "
                  "ms, late, skipped, keyframe (to line several clients' stalls up in time)");
  cmd->add_flag("!--no-progress", args->stream.show_progress, "Do not print progress");
  cmd->callback([args] {
    StreamOptions options = args->stream;
    std::unique_ptr<UnpackedBags> bag;
    options.dataset = dataset_or_bag(args->dataset, args->bag, bag, options.show_progress);
    if (options.name.empty() && bag) options.name = std::filesystem::path(args->bag.bags.front()).stem().string();
    options.encoding = args->encoding == "png" ? ImageEncoding::kPng : ImageEncoding::kRaw;
    if (args->duration_s > 0) options.duration_s = args->duration_s;
    ServerClient client(args->server.server, args->server.token, args->server.ca);
    const StreamReport report = stream_dataset(client, options);
    if (!args->out_trajectory.empty())
      write_trajectory(args->out_trajectory, report.trajectory, report.trajectory_maps,
                       parse_trajectory_format(args->format));
    if (!args->out_live_trajectory.empty())
      write_trajectory(args->out_live_trajectory, report.live_trajectory, report.live_maps,
                       parse_trajectory_format(args->format));
    const nlohmann::json j = stream_json(report);
    if (!args->stats.empty()) write_stats_file(args->stats, j);
    if (!args->frame_log.empty()) write_frame_log(args->frame_log, report);
    print_stream_summary(j);
  });
}

struct UploadArgs {
  ServerArgs server;
  std::string dataset, config, name;
  bool wait = true, progress = true;
  BagArgs bag;
};

void register_upload(CLI::App& app) {
  auto args = std::make_shared<UploadArgs>();
  auto* cmd = app.add_subcommand("upload",
                                 "Upload a recorded sequence (EuRoC ASL, KITTI odometry, or TUM RGB-D with an rgbd "
                                 "config); the "
                                 "server runs it as a stored session");
  add_server_options(cmd, args->server);
  cmd->add_option("--dataset", args->dataset,
                  "Folder holding mav0/, a KITTI odometry sequence (image_0/, image_1/, times.txt, calib.txt), or "
                  "rgb.txt and depth.txt")
      ->check(CLI::ExistingDirectory);
  add_bag_options(cmd, args->bag, false);
  cmd->add_option("--config", args->config,
                  "Config name the server knows (an upload cannot carry a settings file); default euroc/stereo, or a "
                  "KITTI sequence's own from its calib.txt");
  cmd->add_option("--name", args->name, "Session name");
  cmd->add_flag("!--no-wait", args->wait, "Return once uploaded (do not follow the job)");
  cmd->add_flag("!--no-progress", args->progress, "Do not print progress");
  cmd->callback([args] {
    ServerClient client(args->server.server, args->server.token, args->server.ca);
    std::unique_ptr<Progress> sending;
    std::int64_t sent_mb = 0;
    const auto show = [&](std::uint64_t done, std::uint64_t total) {
      if (!args->progress) return;
      if (!sending) sending = std::make_unique<Progress>("upload MB", static_cast<std::int64_t>(total >> 20), true);
      const auto mb = static_cast<std::int64_t>(done >> 20);
      sending->advance(mb - sent_mb);
      sent_mb = mb;
    };
    std::unique_ptr<UnpackedBags> bag;
    const std::filesystem::path dataset = dataset_or_bag(args->dataset, args->bag, bag, args->progress);
    const std::string name =
        args->name.empty() && bag ? std::filesystem::path(args->bag.bags.front()).stem().string() : args->name;
    const std::uint64_t job = client.upload(dataset, args->config, name, show);
    if (sending) sending->finish();
    std::printf("job %llu queued\n", static_cast<unsigned long long>(job));
    if (!args->wait) return;
    nlohmann::json status;
    Progress running("job " + std::to_string(job) + " frames", 0, args->progress);
    std::int64_t shown = 0;
    while (true) {
      status = client.get_json("/v1/jobs/" + std::to_string(job));
      const std::string state = status["state"];
      const auto done = status["frames_done"].get<std::int64_t>();
      running.advance(done - shown);
      shown = done;
      if (state == "done" || state == "failed" || state == "cancelled") break;
      std::this_thread::sleep_for(std::chrono::milliseconds(500));
    }
    running.finish();
    if (status["state"] != "done")
      throw Error("job " + std::to_string(job) + " " + status["state"].get<std::string>() + ": " +
                  status.value("error", std::string("(no reason given)")));
    std::printf(
        "job %llu done: session %llu, %zu of %zu frames tracked, %zu refused", static_cast<unsigned long long>(job),
        static_cast<unsigned long long>(status["session"].get<std::uint64_t>()), status["tracked"].get<std::size_t>(),
        status["frames_total"].get<std::size_t>(), status["rejected"].get<std::size_t>());
    if (status.contains("ate_rmse_m")) std::printf(", ATE %.4f m", status["ate_rmse_m"].get<double>());
    std::printf("\n");
  });
}

void register_listing(CLI::App& app, const char* name, const char* help, const char* path, const char* key) {
  auto args = std::make_shared<ServerArgs>();
  auto json_out = std::make_shared<bool>(false);
  auto* cmd = app.add_subcommand(name, help);
  add_server_options(cmd, *args);
  cmd->add_flag("--json", *json_out, "Print the server's JSON reply");
  const std::string route = path, list_key = key;
  cmd->callback([args, json_out, route, list_key] {
    ServerClient client(args->server, args->token, args->ca);
    const nlohmann::json reply = client.get_json(route);
    if (*json_out) {
      std::printf("%s\n", reply.dump(2).c_str());
      return;
    }
    for (const auto& item : reply.at(list_key)) {
      std::string line =
          list_key.substr(0, list_key.size() - 1) + " " + std::to_string(item["id"].get<std::uint64_t>());
      for (const auto& [k, v] : item.items()) {
        if (k == "id" || v.is_object() || v.is_array()) continue;
        line += "  " + k + "=" + (v.is_string() ? v.get<std::string>() : v.dump());
      }
      std::printf("%s\n", line.c_str());
    }
    if (reply.at(list_key).empty()) std::printf("no %s\n", list_key.c_str());
  });
}

void print_merges(const nlohmann::json& reply) {
  const auto live = reply.value("live_merges", nlohmann::json::array());
  for (const auto& m : live)
    std::printf(
        "map %llu merged live into map %llu (session %llu still running): keyframe %llu ~ %llu, %d matches "
        "(%d keyframes agree), %zu keyframes and %zu points moved, %zu points fused, merge %.1f ms\n",
        m["source_map"].get<unsigned long long>(), m["target_map"].get<unsigned long long>(),
        m["session"].get<unsigned long long>(), m["keyframe"].get<unsigned long long>(),
        m["matched_keyframe"].get<unsigned long long>(), m["matches"].get<int>(), m["verified_keyframes"].get<int>(),
        m["keyframes_moved"].get<std::size_t>(), m["map_points_moved"].get<std::size_t>(),
        m["points_fused"].get<std::size_t>(), m["merge_ms"].get<double>());
  for (const auto& m : reply.at("merges")) {
    std::printf(
        "map %llu merged into map %llu: keyframe %llu ~ %llu, %d matches (%d keyframes agree), %zu keyframes "
        "and %zu points moved, %zu points fused; search %.0f ms, merge %.1f ms, global BA %zu keyframes %.2f s%s\n",
        m["source_map"].get<unsigned long long>(), m["target_map"].get<unsigned long long>(),
        m["keyframe"].get<unsigned long long>(), m["matched_keyframe"].get<unsigned long long>(),
        m["matches"].get<int>(), m["verified_keyframes"].get<int>(), m["keyframes_moved"].get<std::size_t>(),
        m["map_points_moved"].get<std::size_t>(), m["points_fused"].get<std::size_t>(), m["search_ms"].get<double>(),
        m["merge_ms"].get<double>(), m["global_ba"]["keyframes"].get<std::size_t>(),
        m["global_ba"]["seconds"].get<double>(), m["global_ba"]["interrupted"].get<bool>() ? " (interrupted)" : "");
  }
  if (reply.at("merges").empty() && live.empty()) std::printf("no merges\n");
  for (const auto& r : reply.value("refinements", nlohmann::json::array()))
    std::printf("map %llu refined (no other map shares its place): global BA %zu keyframes %.2f s%s\n",
                r["map"].get<unsigned long long>(), r["keyframes"].get<std::size_t>(), r["seconds"].get<double>(),
                r["interrupted"].get<bool>() ? " (interrupted)" : "");
  if (reply.value("pending", std::size_t{0}) > 0)
    std::printf("%zu map(s) waiting for the merging worker\n", reply["pending"].get<std::size_t>());
}

void register_merges(CLI::App& app) {
  auto args = std::make_shared<ServerArgs>();
  auto json_out = std::make_shared<bool>(false);
  auto wait_s = std::make_shared<double>(0.0);
  auto* cmd = app.add_subcommand(
      "merges", "List the map merges of a map server (live ones and the server-wide merging worker's)");
  add_server_options(cmd, *args);
  cmd->add_flag("--json", *json_out, "Print the server's JSON reply");
  cmd->add_option("--wait", *wait_s, "First wait up to this many seconds until no map waits for the merging worker")
      ->check(CLI::NonNegativeNumber);
  cmd->callback([args, json_out, wait_s] {
    ServerClient client(args->server, args->token, args->ca);
    nlohmann::json reply = client.get_json("/v1/merges");
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(*wait_s);
    bool told = false;
    while (reply.value("pending", std::size_t{0}) > 0 && std::chrono::steady_clock::now() < deadline) {
      if (!told && !*json_out)
        std::printf("waiting for the merging worker (%zu map(s))...\n", reply["pending"].get<std::size_t>());
      told = true;
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
      reply = client.get_json("/v1/merges");
    }
    if (*json_out) {
      std::printf("%s\n", reply.dump(2).c_str());
    } else {
      print_merges(reply);
    }
  });
}

void register_trajectory(CLI::App& app) {
  auto args = std::make_shared<ServerArgs>();
  auto session = std::make_shared<std::uint64_t>(0);
  auto out = std::make_shared<std::string>();
  auto format = std::make_shared<std::string>("tum");
  auto* cmd = app.add_subcommand("trajectory", "Download a session's trajectory (poses as the atlas holds them now)");
  add_server_options(cmd, *args);
  cmd->add_option("--session", *session, "Session id")->required();
  cmd->add_option("--out", *out, "Write it to this file (default: print it)");
  cmd->add_option("--format", *format,
                  "Trajectory file format: tum (t tx ty tz qx qy qz qw, seconds) or euroc (the csv of EuRoC's ground "
                  "truth: ns,px,py,pz,qw,qx,qy,qz; what evo_traj euroc reads)")
      ->capture_default_str()
      ->check(CLI::IsMember({"tum", "euroc"}));
  cmd->callback([args, session, out, format] {
    ServerClient client(args->server, args->token, args->ca);
    const std::string text = client.trajectory_tum(*session);
    const TrajectoryFormat chosen = parse_trajectory_format(*format);
    if (out->empty() && chosen == TrajectoryFormat::kTum) {
      std::fwrite(text.data(), 1, text.size(), stdout);
      return;
    }
    std::vector<std::uint64_t> maps;
    const Trajectory t = parse_tum_trajectory(text, "session " + std::to_string(*session), &maps);
    if (out->empty()) {
      const std::string csv = format_euroc_trajectory(t, maps);
      std::fwrite(csv.data(), 1, csv.size(), stdout);
      return;
    }
    write_trajectory(*out, t, maps, chosen);
    const std::set<std::uint64_t> distinct(maps.begin(), maps.end());
    std::string in;
    for (const auto m : distinct) in += (in.empty() ? "" : ", ") + std::to_string(m);
    std::printf("session %llu: %zu poses in map %s -> %s\n", static_cast<unsigned long long>(*session), t.size(),
                in.c_str(), out->c_str());
  });
}

}  // namespace

void register_remote_commands(CLI::App& app) {
  register_merges(app);
  register_trajectory(app);
  register_stream(app);
  register_listing(app, "sessions", "List the sessions of a map server (live, finished and stored)", "/v1/sessions",
                   "sessions");
  register_listing(app, "maps", "List the maps of a map server's atlas", "/v1/maps", "maps");
  register_listing(app, "jobs", "List the upload jobs of a map server", "/v1/jobs", "jobs");
  register_upload(app);
}

}  // namespace orbatlas::cli
