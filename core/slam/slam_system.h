#pragma once
// One SLAM session of a stereo rig, an RGB-D camera or a single camera, with or
// without an IMU (FrameFrontend): the front end and tracking on the caller's thread,
// attached to the mapping of the maps it is in (MappingWorkers: local mapping
// per map, loop closing; its own, or the owner's shared with other sessions),
// working in an atlas the caller owns (so several sessions and several atlases
// can live in one process).
#include <atomic>
#include <functional>
#include <memory>
#include <set>
#include <utility>
#include <optional>
#include <opencv2/core/mat.hpp>
#include <vector>

#include "core/imu/imu_buffer.h"
#include "core/imu/imu_input_check.h"
#include "core/imu/time_offset_estimate.h"
#include "core/io/settings.h"
#include "core/map/atlas.h"
#include "core/slam/mapping_workers.h"
#include "core/slam/session_slam.h"
#include "core/slam/session_wiring.h"
#include "core/slam/slam_stats.h"
#include "core/slam/tracked_frames.h"
#include "core/tracking/frame_frontend.h"
#include "core/tracking/tracker.h"
#include "core/vocabulary/vocabulary.h"

namespace orbatlas {

struct SlamSystemOptions {
  TrackerOptions tracker;  // th_depth_m and the keyframe interval are derived from the settings
  bool relocalization =
      true;  // when recently lost, relocalise against every map of the atlas (SessionWiring::may_enter_map)
  LocalMapperOptions mapper;
  bool loop_closing = true;  // place recognition, loop correction, global BA (not when localising)
  LoopCloserOptions loop;
  // Live map merging (with loop closing): each keyframe is also looked for in
  // the atlas's other maps (those SessionWiring::may_merge_into accepts); a
  // verified place merges the session's active map into that map while the
  // session goes on. With it, a session that stays lost for
  // `new_map_after_failed_relocalizations` frames starts a new map at once
  // (tracking resumes; the new map joins the old one when a place is
  // recognised) instead of waiting tracker.recently_lost_s.
  bool live_merging = true;
  int new_map_after_failed_relocalizations = 5;
  // With IMU settings (a stereo_inertial config): keyframes are linked by the
  // IMU preintegrated between them and each map gets its inertial initialisation
  // (gravity, biases). Off: the IMU is ignored.
  bool inertial = true;
  InertialTrackingOptions inertial_tracking;
  // The camera-IMU clock offset, estimated from the visually tracked frames'
  // rotations and the gyro (core/imu/time_offset_estimate.h) and applied to
  // every increment once known; stats: imu_time_offset_ms.
  ImuTimeOffsetOptions imu_time_offset;
  // What the session's IMU stream may not carry in (core/imu/imu_input_check.h;
  // its rate and ranges come from the settings): dropped, warned of in the
  // stats and the session's status.
  ImuInputCheckOptions imu_input;
  // A stereo front end extracts the right image's features on a second thread
  // while the left image's are extracted (lower latency on an idle machine).
  // Off: one after the other on the tracking thread (no hand-over between
  // threads; a server whose cores are all busy gains nothing from the second).
  bool parallel_stereo_frontend = true;
  // Wait for local mapping to finish each keyframe before the next frame: slower,
  // but the run is deterministic (tests, comparing culling schemes).
  bool synchronous_mapping = false;
  // After the last frame, one global bundle adjustment over every map the
  // session tracked in (offline runs: every covisibility constraint the run
  // found, refined jointly; frames follow through their keyframes). Only with
  // mapping of its own (a shared one is still running for others: the runner
  // of several recordings adjusts their maps once all of them ended).
  bool final_global_ba = false;
  // A single camera with an IMU: its map's scale comes from the IMU alone, and
  // the refinements stop 75 s after the initialisation, each setting the scale
  // from a window of the chain; one more full visual-inertial BA at the end,
  // with every inertial term of the session, sets it from all of them
  // (docs/inertial.md). On: such a session runs the final global BA above, or
  // in the server's shared mapping the global BA at its end
  // (LoopCloserOptions::stream_end_imu_scale, within shared_map_finish_wait_s).
  bool final_ba_for_imu_scale = true;
  GlobalBundleAdjustmentOptions final_ba;
  // With a shared mapping (the server's): at the end, finish() waits at most
  // this long for a global BA of the session's map when other sessions mapped
  // it too and it grew since its last one (LoopCloser::refine_at_stream_end),
  // so the trajectory read after finish() has it. 0: no such adjustment.
  double shared_map_finish_wait_s = 0.0;
  // The longest a frame waits for the atlas's maps while an edit (a merge, a
  // loop correction, a global BA's result, an inertial initialisation being
  // applied) holds them; past it the frame is answered untracked at once
  // (TrackResult::maps_busy) and tracking goes on at the next. 0: as long as
  // the edit takes (offline runs). The server gives real-time sessions
  // --max-maps-wait-ms.
  double max_maps_wait_ms = 0.0;

  // Throws Error naming the first value out of range (also of the parts).
  void check() const;
};

struct TimedPose {
  TimestampNs t_ns = 0;
  MapId map = 0;
  Pose3 T_w_b;
};

class SlamSystem final : public SessionSlam {
 public:
  // `atlas` and `vocabulary` must outlive the session. Throws Error for settings
  // that are not a stereo rig.
  SlamSystem(Atlas& atlas, const SlamSettings& settings, const Vocabulary& vocabulary, SlamSystemOptions options = {},
             SessionWiring wiring = {});
  ~SlamSystem() override;
  SlamSystem(const SlamSystem&) = delete;
  SlamSystem& operator=(const SlamSystem&) = delete;

  // One stereo pair, image and depth image, or image (`right` empty); throws
  // Error on bad images or a timestamp that does not increase.
  TrackResult process(TimestampNs t_ns, const cv::Mat& left, const cv::Mat& right) override;
  void add_imu(const std::vector<ImuSample>& samples) override;
  bool inertial() const { return imu_noise_.has_value(); }
  bool rgbd() const { return rgbd_; }            // frames are an image and its depth image
  bool monocular() const { return monocular_; }  // frames are one image (mono settings)

  // Lets local mapping finish what is queued (its own mapping stops; a shared
  // one goes on for the others) and releases the last frame (so every culled
  // object can be reclaimed). Idempotent; process() may not be called afterwards.
  void finish() override;
  // With a shared mapping and shared_map_finish_wait_s: the wait for the global
  // BA of the session's map at its end (MappingWorkers::refine_at_stream_end).
  // The caller runs it after finish(), without its own locks.
  std::function<bool()> take_end_refinement() override { return std::exchange(end_refinement_, {}); }

  // The maps this session's frames are in now (merges move frames).
  std::set<MapId> tracked_maps() const;
  // One global bundle adjustment over each of `maps` (after finish(): nothing
  // else may edit them, the mapping that fed them included); counted in stats().
  // finish() calls it for the session's maps with --final-ba and mapping of its
  // own; recordings that shared a mapping call it once over all their maps.
  void adjust_maps_globally(const std::set<MapId>& maps);

  // Every tracked frame's body pose, from its reference keyframe's current pose.
  std::vector<TimedPose> trajectory() const;
  // The tracked frames' anchors so far; safe to call from any thread while
  // frames are processed (a checkpoint thread storing the trajectory).
  std::vector<FrameAnchor> anchors_from(std::size_t first) const override;
  std::optional<FrameAnchor> last_anchor() const override { return frames_.last_anchor(); }
  SlamStats stats() const override;
  std::vector<std::string> imu_warnings() const override {
    return imu_input_ ? imu_input_->health().warnings : std::vector<std::string>{};
  }
  std::size_t worker_errors() const override;  // tracking's, and its mapping's when its own
  const FrameFrontend& frontend() const { return *frontend_; }

 private:
  Atlas& atlas_;
  SlamSystemOptions options_;
  std::unique_ptr<FrameFrontend> frontend_;  // stereo pairs, or images with their depth (rgbd)
  bool rgbd_ = false;
  bool monocular_ = false;
  FrameCamera cam_;
  std::unique_ptr<FrameRelocalizer> relocalizer_;
  std::shared_ptr<MappingWorkers> mapping_;  // null when localising
  bool own_mapping_ = false;                 // made here (not the owner's shared one)
  std::unique_ptr<KeyframeSink> sink_;       // the tracker's: into mapping_, or none when localising
  std::unique_ptr<Tracker> tracker_;
  // Visual-inertial (settings with IMU.*, options.inertial): the samples, their
  // noise, and the keyframes linked so far (tracking thread).
  std::optional<ImuNoise> imu_noise_;
  ImuBuffer imu_;
  std::unique_ptr<ImuInputCheck> imu_input_;             // with imu_noise_: what add_imu() lets into imu_
  std::unique_ptr<InertialTracking> inertial_tracking_;  // the tracker's (~SlamSystem drops the tracker first)
  Pose3 T_b_i_;                                          // the IMU in the session's body
  ImuTimeOffset time_offset_;                            // tracking thread
  MapId time_offset_map_ = kInvalidMapId;                // the map its frames were tracked in
  std::atomic<bool> time_offset_known_{false};
  std::atomic<TimestampNs> time_offset_ns_{0};
  std::atomic<std::size_t> imu_linked_{0}, imu_uncovered_{0};
  // The white-noise densities of the last keyframe link (< 0 before one).
  std::atomic<double> link_gyro_density_{-1.0}, link_accel_density_{-1.0};
  bool noisier_imu_logged_ = false;          // the session's thread
  std::atomic<TimestampNs> first_t_ns_{-1};  // the session's first frame
  bool finished_ = false;
  std::function<bool()> end_refinement_;  // set by finish()
  std::size_t final_ba_keyframes_ = 0, final_ba_inertial_edges_ = 0;
  double final_ba_s_ = 0.0;
  TrackedFrames frames_;
  std::size_t keyframes_made_ = 0;
  SampleSummary mapping_wait_ms_;  // Tracker::wait_for_mapping, each wait

  // After each frame: a visually tracked one feeds the clock offset's
  // estimate, which the IMU buffer follows once known.
  void follow_imu_clock(const TrackResult& result);
  // Keeps the densities a keyframe link used for the stats; logs the first
  // time they are a quarter or more above the settings'.
  void note_white_noise(const ImuNoise& used);
};

}  // namespace orbatlas
