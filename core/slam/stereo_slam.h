#pragma once
// One stereo SLAM session: the front end, tracking on the caller's thread and
// local mapping on its own, working on a map of an atlas the caller owns (so
// several sessions and several atlases can live in one process).
#include <functional>
#include <memory>
#include <mutex>
#include <opencv2/core/mat.hpp>
#include <vector>

#include "core/io/settings.h"
#include "core/map/atlas.h"
#include "core/loop/loop_closer.h"
#include "core/mapping/local_mapper.h"
#include "core/slam/session_slam.h"
#include "core/slam/session_wiring.h"
#include "core/slam/slam_stats.h"
#include "core/slam/tracked_frames.h"
#include "core/tracking/stereo_frontend.h"
#include "core/tracking/tracker.h"
#include "core/vocabulary/vocabulary.h"

namespace orbatlas {

struct StereoSlamOptions {
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
  // Wait for local mapping to finish each keyframe before the next frame: slower,
  // but the run is deterministic (tests, comparing culling schemes).
  bool synchronous_mapping = false;
  // After the last frame, one global bundle adjustment over every map the
  // session tracked in (offline runs: every covisibility constraint the run
  // found, refined jointly; frames follow through their keyframes).
  bool final_global_ba = false;
  GlobalBundleAdjustmentOptions final_ba;

  // Throws Error naming the first value out of range (also of the parts).
  void check() const;
};

struct TimedPose {
  TimestampNs t_ns = 0;
  MapId map = 0;
  Pose3 T_w_b;
};

class StereoSlam final : public SessionSlam {
 public:
  // `atlas` and `vocabulary` must outlive the session. Throws Error for settings
  // that are not a stereo rig.
  StereoSlam(Atlas& atlas, const SlamSettings& settings, const Vocabulary& vocabulary, StereoSlamOptions options = {},
             SessionWiring wiring = {});
  ~StereoSlam() override;
  StereoSlam(const StereoSlam&) = delete;
  StereoSlam& operator=(const StereoSlam&) = delete;

  // One stereo pair (throws Error on bad images or a timestamp that does not increase).
  TrackResult process(TimestampNs t_ns, const cv::Mat& left, const cv::Mat& right) override;

  // Lets local mapping finish what is queued, stops it and releases the last
  // frame (so every culled object can be reclaimed). Idempotent; process() may
  // not be called afterwards.
  void finish() override;

  // Every tracked frame's body pose, from its reference keyframe's current pose.
  std::vector<TimedPose> trajectory() const;
  // The tracked frames' anchors so far; safe to call from any thread while
  // frames are processed (a checkpoint thread storing the trajectory).
  std::vector<FrameAnchor> anchors() const override;
  SlamStats stats() const override;
  std::size_t worker_errors() const override;
  const StereoFrontend& frontend() const { return frontend_; }

 private:
  Atlas& atlas_;
  StereoSlamOptions options_;
  StereoFrontend frontend_;
  FrameCamera cam_;
  std::unique_ptr<FrameRelocalizer> relocalizer_;
  std::unique_ptr<LocalMapper> mapper_;
  std::unique_ptr<LoopCloser> loop_closer_;  // null when loop closing is off
  std::unique_ptr<Tracker> tracker_;
  bool finished_ = false;
  std::size_t final_ba_keyframes_ = 0;
  double final_ba_s_ = 0.0;
  // Held for each frame; the loop closer holds it while it edits the map.
  std::shared_ptr<std::mutex> tracking_mutex_ = std::make_shared<std::mutex>();
  TrackedFrames frames_;
  std::size_t keyframes_made_ = 0;
};

}  // namespace orbatlas
