#pragma once
// What the map service (AtlasService, UploadJobs) answers, as data: the HTTP
// layer (wire/service_json.h) turns these into JSON and PLY, tests read
// them directly. No wire format here.
#include <Eigen/Core>
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "core/common/ids.h"
#include "core/common/sample_summary.h"
#include "core/common/timestamp.h"
#include "core/geometry/trajectory.h"
#include "core/imu/imu_noise.h"
#include "core/imu/white_noise_estimate.h"
#include "core/io/settings.h"
#include "core/loop/loop_closer.h"
#include "core/server/map_merge_worker.h"
#include "core/tracking/tracker.h"

namespace orbatlas {

enum class SessionState { kActive, kFinished, kFailed, kStored };
const char* session_state_name(SessionState state);

// What a session does in the atlas: map (track and add keyframes to its map,
// close loops, merge) or localize (track in the stored maps and change nothing:
// no lease, so any number of them share a map, also while it is edited).
enum class SessionMode { kMap, kLocalize };
const char* session_mode_name(SessionMode mode);

// GET /v1/sessions/{id}.
struct SessionStatus {
  SessionId id = 0;
  std::string name;
  SessionState state = SessionState::kActive;
  SensorType sensor = SensorType::kStereo;
  std::optional<SessionMode> mode;  // none for a session of an earlier run (not stored)
  std::size_t frames = 0, tracked = 0, keyframes = 0, rejected_frames = 0, imu_samples = 0;
  std::size_t skipped_frames = 0;    // too late for a real-time session (max_lag_s)
  std::size_t maps_busy_frames = 0;  // answered untracked: the maps were held past the session's bound
  std::size_t worker_errors = 0;
  // What was wrong with the session's IMU stream (gaps, dropped samples, its
  // rate, frames it does not cover), one line per kind; empty when nothing.
  std::vector<std::string> imu_warnings;
  std::string config;    // the config name it was started with ("" for inline settings)
  std::string error;     // why it failed ("" unless failed)
  std::string ended_by;  // who ended it when not the client ("idle_timeout"; "" otherwise)
  struct LastFrame {
    TimestampNs t_ns = 0;
    bool tracked = false;
  };
  std::optional<LastFrame> last_frame;
  std::optional<MapId> map;   // the map its last frame is in now (a merge may have moved it)
  SampleSummary tracking_ms;  // per frame (empty before the first)
  // Where a frame's time in the server went: the whole request (from its
  // handling to the reply), decoding its images, and, inside tracking, waiting
  // for the atlas's maps (held whole by a merge, a loop correction or a global
  // BA's result). Reading the body off the socket comes before and is not counted.
  SampleSummary request_ms, decode_ms, maps_wait_ms;
  // The live pose's jumps at the map's corrections (FrameOutcome::jump_m).
  SampleSummary live_jumps_m;
  struct SlamCounts {
    std::size_t relocalizations = 0, loops = 0;
    // Stereo-inertial sessions: the inertial initialisation of its map (s after
    // its first frame), and the biases found.
    std::optional<double> imu_initialized_at_s;
    ImuBias imu_bias;
    std::optional<double> imu_time_offset_ms;  // the camera-IMU clock offset estimated
    // The white-noise densities of the last keyframe link (SlamStats::imu_white_noise).
    std::optional<WhiteNoiseDensities> imu_white_noise;
    // The frames after its keyframes waiting for local mapping to adjust them
    // (TrackerOptions::max_mapping_wait_ms), and the waits cut at that bound.
    SampleSummary mapping_wait_ms;
    std::size_t mapping_waits_cut = 0;
  };
  std::optional<SlamCounts> slam;  // once finished
};

// GET /v1/maps/{id}.
struct MapSummary {
  MapId id = 0;
  std::size_t keyframes = 0, map_points = 0;
  std::optional<SessionId> live_session;  // the mapping session holding it now (its lease)
  std::vector<SessionId> sessions;        // live sessions whose last frame was tracked in it (any mode)
  // This server maps in and writes it (a shared atlas: another replica owns it
  // when false, and this server only localises in it; always true on SQLite).
  bool writable = true;
  struct Bounds {
    Eigen::Vector3d min, max;
  };
  std::optional<Bounds> bounds_m;  // of its points, in the map's frame (none without points)
};

// GET /v1/maps/{id}/points: the map's good points in its frame, metres.
struct MapPointCloud {
  MapId map = 0;
  std::vector<Eigen::Vector3d> points;
};

// A live merge with the session whose map was merged.
struct LiveMergeRecord {
  SessionId session = 0;
  LiveMerge merge;
};

// GET /v1/merges.
struct MergesReport {
  bool enabled = false;                      // merging on at all
  MapMergeWorkerStats worker;                // the server-wide worker (sessions' ends)
  std::vector<LiveMergeRecord> live_merges;  // the last kMergeHistory
  std::size_t live_merges_total = 0;
};

struct FrameReply {
  SessionId session = 0;
  TrackResult result;
  double tracking_ms = 0.0;
  bool skipped = false;          // too late (SessionRequest::max_lag_s): not tracked
  std::optional<double> jump_m;  // the pose's jump at a correction of the maps (FrameOutcome::jump_m)
};

struct SessionTrajectory {
  Trajectory poses;                 // the frames that resolve, by time
  std::vector<std::uint64_t> maps;  // the map each is in now (after merges)
  std::size_t frames = 0;           // frames the session tracked
  std::size_t unresolved = 0;       // of them, anchored to a keyframe no map has any more
};

// GET /healthz.
struct HealthReport {
  bool shutting_down = false;
  std::size_t live_sessions = 0, maps = 0, merges_pending = 0;
};

}  // namespace orbatlas
