#pragma once
// Streams a recorded sequence (EuRoC ASL, KITTI odometry, TUM RGB-D) to the map server as a live session
// (what `orbatlas stream` does): images are read ahead by a loader thread, each
// stereo pair (the left image alone for a single-camera session) is posted at the sensor rate times `rate` (0: as fast
// as the server answers), the session is finished (stored), and its final trajectory fetched and, with ground truth,
// evaluated.
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "client/api/server_client.h"
#include "core/geometry/trajectory.h"

namespace orbatlas {

struct StreamOptions {
  std::filesystem::path dataset;
  // A config name the server knows or a local settings file (choose_settings);
  // empty: a KITTI sequence's settings from its calib.txt, else euroc/stereo.
  std::string config;
  // Empty: the config's Sensor.type. "mono" (or a mono config): only the left
  // images are sent, and the session localises in the stored maps.
  std::string sensor;
  // "map" or "localize"; empty: map for a stereo rig, localize for a single camera.
  std::string mode;
  std::string name;   // default: the dataset folder's name
  double rate = 0.0;  // 1: real time; 2: twice as fast; 0: no pacing
  // A real-time session (SessionRequest::max_lag_s): the server skips the
  // frames that arrive more than this behind the sensor's clock.
  std::optional<double> max_lag_s;
  ImageEncoding encoding = ImageEncoding::kRaw;
  // Read and decode every image before the first frame is sent (instead of a
  // few ahead while streaming): the clip's raw pixels in memory, and no image
  // decoding competing with a server on the same machine (scripts/bench/capacity.sh).
  bool preload = false;
  // Wait until this wall-clock time (seconds since the Unix epoch) before the
  // first frame, after any preload: clients started together begin together.
  std::optional<double> start_at_unix_s;
  // Stream the (windowed) clip this many times in one session, each pass's
  // timestamps after the last one's (a long run from a short clip: memory
  // over time, scripts/bench/memory.sh). Sessions without an IMU only.
  int repeat = 1;
  double start_s = 0.0;
  std::optional<double> duration_s;
  bool show_progress = true;
  // Asked before each frame: true ends the stream there, and the session is
  // finished as at the clip's end (a client that stops early; a test that needs
  // a live session only while it looks).
  std::function<bool()> stop;

  // Throws Error naming the first value out of range.
  void check() const;
};

struct StreamReport {
  std::uint64_t session = 0;
  std::size_t frames = 0, tracked = 0, rejected = 0, keyframes = 0;
  // With pacing (rate > 0): replies that arrived after the next frame was due.
  std::size_t late_frames = 0;
  std::size_t skipped_frames = 0;     // the server skipped them (max_lag_s): too late
  std::size_t maps_busy_frames = 0;   // answered untracked: an edit held the maps past the session's bound
  std::size_t imu_samples = 0;        // sent (inertial sessions: the recording's imu0)
  std::vector<double> tracking_ms;    // the server's tracking time per frame
  std::vector<double> server_ms;      // the server's time per request (parsing, decoding, tracking)
  std::vector<double> round_trip_ms;  // seen by the client (encoding, transfer, server)
  // One per frame answered (skipped ones too): when it was sent and how it
  // went, to line several clients' stalls up in time (--frame-log).
  struct FrameTiming {
    TimestampNs t_ns = 0;
    std::int64_t sent_unix_us = 0;  // the client's wall clock
    double round_trip_ms = 0.0, server_ms = 0.0, tracking_ms = 0.0;
    bool late = false;  // its reply came after the next frame was due
    bool skipped = false, keyframe = false;
    bool maps_busy = false;                     // answered untracked: an edit held the maps past the bound
    int local_keyframes = 0, local_points = 0;  // the local map the server tracked the frame in
    double maps_wait_ms = 0.0;                  // the server's wait for its maps (in tracking_ms)
  };
  std::vector<FrameTiming> frame_timings;
  double wall_s = 0.0;
  // How long the finish request took (the server stores the session's last
  // frames before it replies); the trajectory is fetched right after.
  double finish_ms = 0.0;
  Trajectory trajectory;  // the server's final trajectory (after the session finished)
  std::vector<std::uint64_t> trajectory_maps;
  std::vector<std::uint64_t> reply_maps;  // per tracked frame: the map its reply named then
  // The poses the replies carried (what a device steers by), with their maps:
  // one per tracked frame, as it was answered, never corrected afterwards.
  Trajectory live_trajectory;
  std::vector<std::uint64_t> live_maps;
  // The replies' jumps at corrections of the maps (the server's jump_m).
  std::vector<double> live_jumps_m;
  std::optional<double> live_ate_rmse_m;  // the live poses against the ground truth (the final's alignment)
  std::size_t live_ate_poses = 0;
  // Frames sent whose reply carried a pose.
  double live_fraction() const {
    return frames > 0 ? static_cast<double>(live_trajectory.size()) / static_cast<double>(frames) : 0.0;
  }
  std::optional<double> ate_rmse_m;  // when the dataset has ground truth (SE3 alignment)
  std::size_t ate_poses = 0;         // the trajectory's poses the ATE compares (those with ground truth)
  bool ate_sim3 = false;             // a single camera that mapped: the camera's poses, Sim3 alignment
  nlohmann::json finish_status;
  double fps() const { return wall_s > 0 ? static_cast<double>(frames) / wall_s : 0.0; }
};

// Throws Error when the dataset cannot be read or the server refuses the
// session; frames the server refuses as bad input are counted (`rejected`).
StreamReport stream_dataset(ServerClient& client, const StreamOptions& options);

}  // namespace orbatlas
