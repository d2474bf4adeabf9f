#pragma once
// The offset between a camera's clock and its IMU's, from the rotation both
// measure (VINS-Mono and OpenVINS estimate it online; ORB-SLAM3 trusts the
// stamps): the image stamped t was taken at IMU time t + offset. The gyro
// integrated between IMU times t_a + offset and t_b + offset must turn as the
// visual poses of the frames stamped t_a and t_b do; a wrong offset shifts the
// integration window and leaves a residual that follows the change of the
// angular rate, which the gyro bias (a constant rate) cannot explain.
//
// ImuTimeOffset collects a session's visually tracked frames' rotations and,
// every `every_s`, fits the offset and the gyro bias to the last `window_s` of
// them (a coarse scan, then a golden-section search, the bias solved at each
// offset in closed form); a window in which the rig turned too little is
// skipped. The session's estimate is the median of the latest windows'.
// One thread (the session's tracking).
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <deque>
#include <optional>
#include <vector>

#include "core/common/timestamp.h"
#include "core/io/euroc_types.h"

namespace orbatlas {

struct ImuTimeOffsetOptions {
  bool enabled = true;
  double max_offset_s = 0.05;  // searched within +- this
  double window_s = 10.0;      // frames fitted together
  double every_s = 2.0;        // a new fit this often
  double pair_s = 0.5;         // the two frames of a residual this far apart
  // A window is used only when the angular rate changed enough in it (RMS of
  // its change over pair_s, rad/s): the offset is seen through that change.
  double min_rate_change = 0.1;
  // A pair whose images and gyro (no offset) disagree by more (rad) than the
  // window's median disagreement (the bias's part) straddles a jump of the map and is left out; a window that loses a
  // quarter of its pairs so is skipped.
  double max_pair_residual = 0.1;
  std::size_t min_windows = 3;   // estimates before one is reported
  std::size_t max_windows = 30;  // the median is of the latest this many

  // Throws Error naming the first value out of range.
  void check() const;
};

class ImuTimeOffset {
 public:
  explicit ImuTimeOffset(ImuTimeOffsetOptions options = {});

  // A visually tracked frame: its stamp and the IMU's rotation in the world
  // (R_w_i). Frames must come in time order; a jump of the map (a new map,
  // a loop correction) calls reset().
  void add_frame(TimestampNs t_ns, const Eigen::Quaterniond& q_w_i);
  // Fits a window when one is due; `samples`: the IMU (in time order) covering
  // the frames. Returns true when the estimate changed.
  bool update(const std::vector<ImuSample>& samples);
  void reset();

  // The session's estimate (seconds; the IMU time of an image is its stamp
  // plus this), once min_windows windows were fitted.
  std::optional<double> offset_s() const;
  std::size_t windows() const { return estimates_.size(); }

  // One window's fit (exposed for tests): the offset minimising the rotation
  // residuals of `frames` against `samples`, and the residuals' curvature
  // there; none when the window does not show the rate change needed.
  struct Frame {
    TimestampNs t_ns = 0;
    Eigen::Quaterniond q_w_i;
  };
  struct Fit {
    double offset_s = 0.0;
    Eigen::Vector3d gyro_bias = Eigen::Vector3d::Zero();
    double rms_rad = 0.0;  // residual per pair at the offset found
  };
  static std::optional<Fit> fit(const std::vector<Frame>& frames, const std::vector<ImuSample>& samples,
                                const ImuTimeOffsetOptions& options);

 private:
  ImuTimeOffsetOptions options_;
  std::deque<Frame> frames_;
  TimestampNs last_fit_ns_ = 0;
  std::deque<double> estimates_;
};

}  // namespace orbatlas
