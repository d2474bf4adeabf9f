#pragma once
// The tracking state machine of one session (ORB-SLAM3's Tracking): stereo (or
// RGB-D) initialisation from one frame, monocular initialisation from two
// (a camera without depth: bf 0), the motion model, the reference
// keyframe by bag of words, the local map, the keyframe decision, and the states
// NOT_INITIALIZED -> OK <-> RECENTLY_LOST -> LOST. When tracking is lost for good
// a new map is started in the atlas and initialised from the next stereo frame.
// Runs on the caller's thread; keyframes go to a KeyframeSink (the local mapper).
#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include "core/common/flat_id_set.h"
#include "core/map/atlas.h"
#include "core/map/frame_anchor.h"
#include "core/tracking/frame.h"
#include "core/tracking/frame_relocalizer.h"
#include "core/tracking/inertial_tracking.h"
#include "core/tracking/keyframe_sink.h"
#include "core/tracking/monocular_initializer.h"
#include "core/tracking/projection_search.h"
#include "core/vocabulary/vocabulary.h"

namespace orbatlas {

enum class TrackingState { kNotInitialized, kOk, kRecentlyLost, kLost };
const char* tracking_state_name(TrackingState state);

struct TrackerOptions {
  int min_init_stereo_points = 500;  // stereo matches needed to start a map
  double th_depth_m = 3.5;           // close / far stereo points (ORB-SLAM's ThDepth * baseline)
  // The keyframe decision's tracked close points (ORB-SLAM's nTrackedClose)
  // are only those a keyframe of this session observes: in a map that other
  // sessions map too, a close point only their keyframes hold counts as not
  // yet tracked, so a session flying through another's map still makes the
  // keyframes whose close stereo observations tie its path to the map (without
  // them its path came out 0.1-0.2 % short; docs/mapping.md, "A session's own
  // close points"). A session alone owns every point: nothing changes.
  // false: ORB-SLAM's count.
  bool own_close_points = true;
  int max_frames_between_keyframes = 20;  // a keyframe at least this often (the frame rate)
  // Visual-inertial sessions (ORB-SLAM3): a keyframe at least every this many
  // seconds while local mapping takes one, so the IMU between keyframes stays
  // short to preintegrate. 0: off.
  double max_keyframe_interval_s = 0.0;
  int min_inliers = 30;                 // after the local-map search
  int min_inliers_after_recovery = 50;  // during the first second after a relocalisation
  // With the IMU (a frame predicted in an inertially initialised map; ORB-SLAM3's
  // stereo- and monocular-inertial rules): the IMU holds the pose, so fewer
  // points do; while recently lost, more than 10 bring the session back.
  int min_inliers_inertial = 15;
  int min_inliers_inertial_recently_lost = 11;
  double recently_lost_s = 5.0;  // then LOST and a new map
  // When > 0: LOST (and a new map) after this many frames in a row that the
  // relocaliser did not place, however short the time. For sessions whose
  // maps are merged live (the new map joins the old one when a place is
  // recognised): tracking resumes at once instead of waiting to come back to
  // a mapped place. 0: only recently_lost_s counts.
  int new_map_after_failed_relocalizations = 0;
  // Before the frame after a keyframe is tracked, local mapping is given up to
  // this long to adjust that keyframe (its local BA; Tracker::wait_for_mapping).
  // A wait that is never cut makes a session's map independent of the load on
  // the machine, as --synchronous does; the price is latency whenever a local
  // BA outlasts a frame interval (docs/mapping.md, "Tracking's wait for its
  // keyframe"). 0 (the default): tracking never waits, as ORB-SLAM.
  double max_mapping_wait_ms = 0.0;
  // The longest wait allowed, given to every session that is not real-time
  // (an offline run, an upload, a stream without max_lag_s).
  static constexpr double kLongestMappingWaitMs = 10000.0;
  // At most this many keyframes in a frame's local map, those observing its points first.
  int max_local_keyframes = 80;
  int min_keyframes_to_keep_map = 10;  // a map lost with fewer keyframes goes straight to LOST
  // Localisation on stored maps: no keyframe and no map is ever made; the first
  // frames, and every frame after tracking is lost, are relocalised against every
  // map of the atlas (a relocaliser is required).
  bool localization_only = false;
  // A new session's first frame is first relocalised against the stored maps
  // (a relocaliser is required): when the place is recognised the session
  // tracks in that map, in its frame, and makes no map of its own; otherwise a
  // new map starts as usual (and may be merged later).
  bool start_in_stored_map = false;
  // A camera without depth (bf 0) that maps: how its maps start.
  MonocularInitializerOptions monocular;

  // Throws Error naming the first value out of range.
  void check() const;
};

struct TrackResult {
  TimestampNs t_ns = 0;
  TrackingState state = TrackingState::kNotInitialized;
  bool tracked = false;  // has a pose
  // Tracked by the IMU alone (visual-inertial sessions): the pose is the IMU's
  // prediction from the last frame; the images were not tracked.
  bool by_imu = false;
  Pose3 T_w_b;  // valid when tracked, in map `map`
  MapId map = 0;
  bool keyframe = false;       // a keyframe was made from this frame
  KeyframeId keyframe_id = 0;  // its id, when `keyframe`
  int inliers = 0;
  // The local map the frame was tracked in (0 when it was not tracked in one):
  // its keyframes, and the map points of theirs projected into the frame.
  int local_keyframes = 0;
  int local_points = 0;
  // The wait for the atlas's maps before tracking (TrackedFrames: a loop
  // correction, a merge or a global BA's result being applied holds them).
  double maps_wait_ms = 0.0;
  // The maps were held by an edit for longer than the session may wait
  // (SlamSystemOptions::max_maps_wait_ms): the frame was answered untracked
  // at once, and tracking goes on from the frame before it at the next one.
  bool maps_busy = false;
  // The atlas's whole-map edits when the frame was tracked (Atlas::maps_edits):
  // more than at the frame before, and the pose may have jumped with a correction.
  std::uint64_t maps_edits = 0;
};

class Tracker {
 public:
  // `atlas`, `vocabulary` and `sink` must outlive the tracker; `cam.camera` too.
  // `relocalizer` (may be null: then only the last reference keyframe's
  // neighbourhood is searched when recently lost) must outlive the tracker too.
  Tracker(Atlas& atlas, const Vocabulary& vocabulary, KeyframeSink& sink, FrameCamera cam, Pose3 T_b_c,
          TrackerOptions options, FrameRelocalizer* relocalizer = nullptr);

  // Tracks one frame (timestamps strictly increasing; throws Error otherwise).
  TrackResult track(Frame frame);
  // Called before a frame is made and tracked: when the last frame made a
  // keyframe, waits (at most max_mapping_wait_ms) until local mapping has
  // adjusted it, so this frame tracks in the adjusted map; a wait that ends
  // at the bound is taken up again by the next frame (each frame waits at most
  // the bound). Returns the time waited [ms]; none when there was nothing to
  // wait for (or waits are off).
  std::optional<double> wait_for_mapping();
  std::size_t mapping_waits_cut() const { return mapping_waits_cut_; }  // ended at max_mapping_wait_ms

  TrackingState state() const { return state_; }
  MapId map_id() const { return map_ ? map_->id() : kInvalidMapId; }  // the map it is in (tracking thread)
  // The anchor of the last frame tracked (none before one). The session's
  // trajectory is kept by its owner (TrackedFrames), once.
  const std::optional<FrameAnchor>& last_anchor() const { return last_anchor_; }
  std::size_t maps_started() const { return maps_started_; }
  std::size_t maps_followed() const { return maps_followed_; }  // merges tracking followed
  std::size_t relocalizations() const { return relocalizations_; }
  // Slots of new keyframes that local mapping filled while tracking was
  // filling them (handled: the point local mapping put there is used).
  std::size_t slot_races() const { return slot_races_; }
  // Times the anchors were scaled with their map (Map::rescale: a monocular
  // map made metric by its IMU); a copy of anchors() is stale after one.
  // Monocular: two-view reconstructions tried, and maps started from them.
  std::size_t monocular_attempts() const { return mono_initializer_ ? mono_initializer_->attempts() : 0; }
  std::size_t monocular_starts() const { return monocular_starts_; }
  // Visual-inertial tracking (not owned; it must outlive the tracker; may be
  // null): once a map is inertially initialised, frames are predicted and
  // optimised with the IMU, and frames that cannot be tracked visually are
  // bridged by it for a while. Set before the first frame.
  void set_inertial(InertialTracking* inertial) { inertial_ = inertial; }
  // Drops the last frame and the keyframes tracking holds (end of a session), so
  // that nothing keeps culled objects alive; the anchors stay.
  void release_frames();
  // Told of each keyframe made, with the keyframe this tracker made before it
  // (null at a map's first; it may be in another map), before local mapping
  // gets it (the session links them by its IMU). Set before the first frame.
  void set_keyframe_listener(
      std::function<void(const std::shared_ptr<KeyFrame>& made, const std::shared_ptr<KeyFrame>& previous)> listener) {
    keyframe_listener_ = std::move(listener);
  }

 private:
  // The steps of track(), in order.
  void accept_frame(const Frame& frame);  // timestamps increase, arrays consistent
  // First frame of a mapping session: track in a stored map that knows the place.
  bool join_stored_map(Frame& frame, TrackResult& result);
  // Localisation only, not (or no longer) localised: relocalise in the stored maps.
  bool localize_in_stored_maps(Frame& frame, TrackResult& result);
  // Motion model, else reference keyframe (else relocalisation when recently
  // lost), then the local map.
  bool track_from_last_frame(Frame& frame);
  void update_state(const Frame& frame, bool ok);                // OK / RECENTLY_LOST / LOST
  void after_tracked(Frame& frame, TrackResult& result);         // velocity, a keyframe when needed
  void finish_frame(Frame frame, bool ok, TrackResult& result);  // result, anchor, last frame
  bool initialize(Frame& frame);
  bool initialize_monocular(Frame& frame);  // two views (bf 0)
  bool track_motion_model(Frame& frame);
  bool track_from_imu_prediction(Frame& frame);  // the local map from the predicted pose
  bool track_reference_keyframe(Frame& frame, const std::shared_ptr<KeyFrame>& keyframe);
  bool recover(Frame& frame);
  bool track_local_map(Frame& frame);
  void update_local_map(const Frame& frame);
  bool need_new_keyframe(const Frame& frame, int inliers) const;
  bool observed_by_own_keyframe(const MapPoint& point) const;
  void create_keyframe(Frame& frame, bool all_stereo_points);
  std::shared_ptr<KeyFrame> new_keyframe(Frame& frame);    // in the map, with no points yet
  void keyframe_made(std::shared_ptr<KeyFrame> keyframe);  // the listener, the sink, the bookkeeping
  void ensure_bow(Frame& frame) const;
  void start_new_map();
  // The active map was merged into another (live map merging): continue there.
  void follow_merged_map();
  void refresh_last_frame_pose();
  // The last frame's reference keyframe changed scale since the last frame
  // (KeyFrame::units: a rescale, a merge, a Sim(3) loop): what the tracker
  // keeps relative to it (the last frame's pose, the motion model, the IMU
  // velocity) is scaled with it.
  void adopt_reference_units();

  Atlas& atlas_;
  const Vocabulary& vocabulary_;
  KeyframeSink& sink_;
  FrameRelocalizer* const relocalizer_;  // not owned, may be null
  const FrameCamera cam_;
  const Pose3 T_b_c_;
  const TrackerOptions options_;
  const bool monocular_;                                    // no depth: two-view initialisation
  std::unique_ptr<MonocularInitializer> mono_initializer_;  // when monocular_ and mapping

  TrackingState state_ = TrackingState::kNotInitialized;
  std::shared_ptr<Map> map_;
  std::function<void(const std::shared_ptr<KeyFrame>&, const std::shared_ptr<KeyFrame>&)> keyframe_listener_;
  std::optional<Frame> last_;
  std::optional<Pose3> velocity_;         // T_last_current of the body, when the last two frames were tracked
  InertialTracking* inertial_ = nullptr;  // not owned, may be null
  std::optional<Pose3> imu_prediction_;   // of this frame's T_w_b, by the IMU
  std::shared_ptr<KeyFrame> reference_;
  std::shared_ptr<KeyFrame> last_keyframe_;
  FlatIdSet own_keyframes_;                   // ids of every keyframe this tracker made (own_close_points)
  std::optional<KeyframeId> last_reference_;  // of the last frame, for its pose refresh
  Pose3 T_ref_last_;
  double reference_units_ = 1.0;  // the units of the last frame's reference keyframe then
  std::vector<std::shared_ptr<KeyFrame>> local_keyframes_;
  std::int64_t frame_index_ = 0, last_keyframe_index_ = 0, last_recovery_index_ = -1000000;
  TimestampNs last_t_ns_ = 0;
  bool has_last_t_ = false;
  TimestampNs lost_since_ns_ = 0;
  int failed_relocalizations_ = 0;  // in a row, while recently lost
  std::size_t maps_started_ = 0, relocalizations_ = 0, maps_followed_ = 0, slot_races_ = 0, monocular_starts_ = 0;
  std::optional<MapId> awaiting_adjustment_;  // the map of the last keyframe made, until wait_for_mapping()
  std::size_t mapping_waits_cut_ = 0;
  std::optional<FrameAnchor> last_anchor_;
  FlatIdSet local_points_seen_;  // track_local_map's points already taken, kept between frames
  // track_local_map's projected points; empty between frames (kept for its capacity).
  std::vector<ProjectedPoint> local_candidates_;
  int local_points_ = 0;  // the last track_local_map's projected points (TrackResult::local_points)
};

}  // namespace orbatlas
