#pragma once
// What a session of the server drives, whatever its camera: stereo SLAM
// (SlamSystem), or a single camera localising in stored maps (MonoLocalizer).
#include <functional>
#include <opencv2/core/mat.hpp>
#include <optional>
#include <vector>

#include "core/map/frame_anchor.h"
#include "core/slam/slam_stats.h"
#include "core/tracking/tracker.h"

namespace orbatlas {

class SessionSlam {
 public:
  virtual ~SessionSlam() = default;
  // One frame: a stereo pair, or one image (`right` empty) for a single camera.
  // DataError for a frame this session cannot take (wrong size, a pair where
  // one image is expected or the reverse, a timestamp that does not increase).
  virtual TrackResult process(TimestampNs t_ns, const cv::Mat& left, const cv::Mat& right) = 0;
  // IMU samples up to (and just past) the next frame, in time order (DataError
  // for one that is not after the previous, keeping none of the batch). A
  // session without an IMU in its settings, or that does not fuse it yet,
  // ignores them; one that fuses it drops samples it cannot use (not finite,
  // a stuck axis, saturated) and says so in imu_warnings().
  virtual void add_imu(const std::vector<ImuSample>& samples) { (void)samples; }
  // What was wrong with the IMU stream so far, one line per kind (any thread).
  virtual std::vector<std::string> imu_warnings() const { return {}; }
  // Stops the session's workers; process() may not be called afterwards. Idempotent.
  virtual void finish() = 0;
  // After finish(): what is left of the end, to run without the caller's locks
  // (it may wait for seconds; SlamSystem: the global BA of a map other sessions
  // mapped too). True when done; empty when nothing is left. Once.
  virtual std::function<bool()> take_end_refinement() { return {}; }
  // The tracked frames' anchors from the first-th on (they only ever follow);
  // safe from any thread.
  virtual std::vector<FrameAnchor> anchors_from(std::size_t first) const = 0;
  std::vector<FrameAnchor> anchors() const { return anchors_from(0); }
  virtual std::optional<FrameAnchor> last_anchor() const = 0;  // none before a tracked frame
  virtual SlamStats stats() const = 0;
  // Errors contained by the session's workers so far (cheap; any thread).
  virtual std::size_t worker_errors() const = 0;
};

}  // namespace orbatlas
