#pragma once
// Where a monocular map starts (ORB-SLAM's MonocularInitialization):
// the first frame with enough keypoints becomes the reference; each following
// frame is matched to it (finest-level keypoints, searched around where they
// were last matched, ratio and rotation checks) and, with enough matches, the
// two views are reconstructed (homography or fundamental matrix,
// core/estimators/two_view_reconstruction.h). A reconstruction with enough
// triangulated points starts the map; too few matches replace the reference by
// the frame, and so does a reference grown too old (the scene has changed).
// The result is the relative pose (unit baseline: the map's scale is
// arbitrary) and the points in the reference camera; the tracker makes the
// map of it. Owned by one tracker, on its thread.
#include <Eigen/Core>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/estimators/two_view_reconstruction.h"
#include "core/tracking/frame.h"

namespace orbatlas {

struct MonocularInitializerOptions {
  int min_keypoints = 100;           // a frame with fewer neither starts nor continues an attempt
  int min_matches = 100;             // with the reference (else the frame becomes the reference)
  float search_radius_px = 100.0f;   // around a keypoint's last match (ORB-SLAM's window of 100)
  int min_points = 100;              // triangulated by the reconstruction
  double max_reference_age_s = 3.0;  // a reference older than this is replaced
  TwoViewOptions two_view;           // focal_px is set from the camera

  // Throws Error naming the first value out of range.
  void check() const;
};

struct MonocularStart {
  Frame reference;  // the first view (as offered)
  Pose3 T_c2_c1;    // the current camera from the reference camera; |t| = 1
  // Triangulated matches: keypoint of the reference, keypoint of the current
  // frame, and the point in the reference camera's frame.
  struct Point {
    std::size_t reference_keypoint = 0, current_keypoint = 0;
    Eigen::Vector3d p_c1;
  };
  std::vector<Point> points;
  TwoViewModel model = TwoViewModel::kNone;
  double parallax_deg = 0.0;
};

class MonocularInitializer {
 public:
  MonocularInitializer(MonocularInitializerOptions options, double focal_px);

  // Offers the next frame (keypoint geometry and grid filled): a start when
  // it and the reference reconstruct, else nullopt (the frame may have become
  // the new reference). Timestamps increase (the tracker checks).
  std::optional<MonocularStart> offer(const Frame& frame);
  void reset();  // forget the reference (the tracker starts again)

  bool has_reference() const { return reference_.has_value(); }
  std::size_t attempts() const { return attempts_; }  // reconstructions tried
  const std::string& last_failure() const { return last_failure_; }

 private:
  void take_as_reference(const Frame& frame);

  MonocularInitializerOptions options_;
  std::optional<Frame> reference_;
  std::vector<Eigen::Vector2f> predicted_;  // per reference keypoint: where to search (NaN: not searched)
  std::size_t attempts_ = 0;
  std::string last_failure_;
};

}  // namespace orbatlas
