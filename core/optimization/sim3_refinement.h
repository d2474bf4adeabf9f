#pragma once
// Non-linear refinement of the similarity S_1_2 between two keyframes from 3D-3D
// matches: ORB-SLAM's Optimizer::OptimizeSim3. The points are constants; S_1_2
// (7 dof, or 6 with the scale fixed) minimises the bidirectional reprojection
// error, for every match (sim3_costs.h):
//
//   |uv1 - project1(S_1_2 * p_c2)|^2 / sigma1^2 + |uv2 - project2(S_1_2^-1 * p_c1)|^2 / sigma2^2
//
// each term under a Huber kernel of delta sqrt(chi2_threshold). Then, as ORB-SLAM:
// a match whose either term has chi2 > chi2_threshold (or cannot be projected) is
// dropped, and the rest is optimised again (10 more iterations when something
// was dropped, 5 otherwise). ORB-SLAM's loop closing uses chi2_threshold = 10;
// a second, narrower pass after guided matching is the caller's choice.
// Matches are in the keyframes' camera frames (sim3_match.h).
#include <cmath>
#include <cstdint>
#include <vector>

#include "core/camera/camera.h"
#include "core/geometry/sim3.h"
#include "core/optimization/sim3_match.h"

namespace orbatlas {

struct Sim3RefinementOptions {
  double chi2_threshold = 10.0;     // ORB-SLAM's th2 (LoopClosing::ComputeSim3)
  bool fix_scale = false;           // stereo / RGB-D: S_1_2 stays rigid (its initial scale)
  int first_iterations = 5;         // Levenberg-Marquardt, all matches
  int second_iterations = 10;       // after outliers were dropped
  int second_iterations_clean = 5;  // when no outlier was dropped
  bool robust_second_pass = true;   // ORB-SLAM keeps the Huber kernel in the second pass
  int min_inliers = 10;             // fewer matches left after the first pass: failure (ORB-SLAM returns 0)

  // Throws Error naming the first value out of range.
  void check() const;
};

struct Sim3RefinementResult {
  bool success = false;  // the second pass ran (enough matches survived the first)
  Sim3 S_1_2;            // refined; the initial estimate on failure
  // Per match at the final S_1_2: both terms project with chi2 <= chi2_threshold.
  std::vector<std::uint8_t> inliers;  // all 0 on failure
  int inlier_count = 0;
  int iterations = 0;  // Levenberg-Marquardt iterations, both passes
};

// The cameras are the models of image 1 and image 2 (the keypoints uv1 / uv2).
// Throws Error on a non-positive level sigma2 or a non-positive threshold.
Sim3RefinementResult refine_sim3(const Sim3& S_1_2_initial, const std::vector<Sim3Match>& matches,
                                 const Camera& camera1, const Camera& camera2,
                                 const Sim3RefinementOptions& options = {});

}  // namespace orbatlas
