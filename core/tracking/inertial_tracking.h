#pragma once
// What the IMU adds to one session's tracking once its map is inertially
// initialised (ORB-SLAM3's Tracking with IMU): the pose of each frame predicted
// from the last one by the IMU between them; the frame's pose, IMU velocity and
// biases optimised against its map points and the last frame's state together;
// and, while the images show nothing to track, the predicted pose on its own
// (frames tracked by the IMU) for a bounded time.
//
// Owned by the session, used on its tracking thread only. The last frame's
// velocity is kept in that frame's IMU frame, so that moving the frame (its
// reference keyframe moved, the map was turned to gravity or corrected by a
// loop) carries the velocity along.
#include <memory>
#include <optional>

#include "core/imu/imu_buffer.h"
#include "core/map/map.h"
#include "core/optimization/pose_optimizer.h"
#include "core/tracking/frame.h"
#include "core/tracking/frame_camera.h"

namespace orbatlas {

struct InertialTrackingOptions {
  // Frames tracked by the IMU alone after the last visually tracked one, for
  // at most this long (then the frames are lost, as without an IMU).
  double max_imu_only_s = 1.5;
  // The prior of a last state that no visual-inertial optimisation produced
  // (the map's first inertial frame, the first after frames tracked by the
  // IMU): sigmas of rotation (rad), camera position (m) and velocity (m/s);
  // after frames tracked by the IMU the position's grows by the velocity's
  // times the time bridged.
  double loose_rotation_sigma = 0.01;
  double loose_position_sigma = 0.02;
  double loose_velocity_sigma = 0.2;
  // The biases are held near the map's estimate: the random walk over this many
  // seconds (the noise's walk densities) is the prior's sigma.
  double bias_prior_window_s = 10.0;

  // Throws Error naming the first value out of range.
  void check() const;
};

class InertialTracking {
 public:
  // `imu` (the session's samples) must outlive this. T_b_i, T_b_c: the IMU and
  // the tracking camera in the body.
  InertialTracking(const ImuBuffer& imu, const ImuNoise& noise, const Pose3& T_b_i, const Pose3& T_b_c,
                   InertialTrackingOptions options = {});

  // The body pose of the frame at `t_ns` predicted from `last` (the last frame,
  // its pose current) by the IMU; none when the map is not inertially
  // initialised, the last frame's state is unknown or the IMU does not cover
  // the time between. Keeps the increments for optimize() and imu_only().
  // `own_bias`: this session's IMU biases (its newest keyframe's, as ORB-SLAM3
  // takes them), which the prediction and the frame's bias prior use; none:
  // the map's estimate (a session with no keyframe in the map yet). A map
  // several sessions share holds one estimate, of whichever IMU its newest
  // keyframe saw, which another device's IMU does not share.
  std::optional<Pose3> predict(const Map& map, const Frame& last, TimestampNs t_ns,
                               const std::optional<ImuBias>& own_bias = std::nullopt);
  // The frame's visual-inertial pose optimisation after predict() for it (its
  // map points associated); the inliers, or none without a prediction (the
  // visual optimisation is then the caller's).
  std::optional<int> optimize(Frame& frame, const FrameCamera& cam, const PoseOptimizerOptions& options = {});
  // Whether a frame at `t_ns` that could not be tracked visually may take the
  // prediction made for it as its pose.
  bool may_bridge(TimestampNs t_ns) const;

  enum class Outcome { kVisual, kImuOnly, kLost };
  // After each frame: its state is remembered for the next (`previous`: the
  // frame before it, for a first velocity from the two poses).
  void frame_done(const Frame& frame, const Frame* previous, Outcome outcome);
  // The rotation of the body at `t_ns` (R_w_b) that points the gravity its
  // IMU measured in the last half second (the mean specific force, up) along
  // the world's -z, turning it the least: a new map starts level, so that its
  // inertial initialisation turns it by what the start was off (a degree or
  // two) instead of by the camera's tilt (tens of degrees, about the newest
  // keyframe: the device's earlier poses move by it). A push along gravity
  // (a rig lifted) does not tilt it, one across does (3 m/s^2: 17 deg). None
  // without a sample there, or from a mean under half or over twice gravity's
  // magnitude (falling, or thrown about).
  std::optional<Eigen::Quaterniond> level_rotation(TimestampNs t_ns) const;
  // A new map, or the session is lost: nothing carries over.
  void reset();
  // The map's units changed by `factor` (Map::rescale: a monocular map made
  // metric): the last frame's velocity, kept in them, follows.
  void rescale(double factor);

  // The IMU state the frame at `t_ns` was given before frame_done() for it:
  // its visual-inertial estimate, else the prediction (velocity in the world,
  // biases); none without a prediction for that frame.
  struct FrameImuState {
    Eigen::Vector3d v_w = Eigen::Vector3d::Zero();
    ImuBias bias;
  };
  std::optional<FrameImuState> frame_state(TimestampNs t_ns) const;

  bool has_state() const { return last_.has_value(); }
  std::size_t optimized_frames() const { return optimized_frames_; }
  const ImuBias& last_bias() const { return bias_; }

 private:
  struct LastState {
    TimestampNs t_ns = 0;
    Eigen::Vector3d v_i = Eigen::Vector3d::Zero();  // the IMU's velocity, in its own frame
    // From the optimisation (its velocity block in the frame's IMU frame), else the loose prior.
    std::optional<StateCovariance> covariance;
  };
  struct Prediction {
    TimestampNs t_ns = 0;
    std::shared_ptr<const Preintegration> increments;
    Map::InertialState map;
    Pose3 last_T_w_b;
    Eigen::Vector3d last_v_w = Eigen::Vector3d::Zero();
    ImuState predicted;
    std::optional<InertialPoseEstimate> estimate;  // filled by optimize()
  };
  // The loose prior, its position sigma grown by the velocity sigma over the
  // `bridged_s` seconds the last state was carried by the IMU alone.
  StateCovariance loose_covariance(double bridged_s) const;
  ImuState imu_state(const Pose3& T_w_b, const Eigen::Vector3d& v_w) const;

  const ImuBuffer& imu_;
  const ImuNoise noise_;
  const Pose3 T_b_i_, T_b_c_, T_c_i_;
  const InertialTrackingOptions options_;
  std::optional<LastState> last_;
  std::optional<Prediction> prediction_;
  TimestampNs last_visual_ns_ = 0;
  ImuBias bias_;
  std::size_t optimized_frames_ = 0;
};

}  // namespace orbatlas
