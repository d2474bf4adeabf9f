#pragma once
// RANSAC estimate of the similarity S_1_2 between two keyframes from 3D-3D map
// point matches, after ORB-SLAM's Sim3Solver (loop detection / map merging):
//
// - hypothesis: Horn's closed form (horn_absolute_orientation) on 3 random matches,
//   with the scale fixed to 1 for stereo / RGB-D maps (SE3) or estimated (Sim3);
// - score: a match is an inlier when BOTH reprojections fit: S_1_2 * p_c2 into
//   image 1 against uv1, and S_2_1 * p_c1 into image 2 against uv2, each with
//   squared pixel error < chi2 * level_sigma2 (chi2 = 9.210, the 99% quantile
//   for 2 dof, ORB-SLAM's value);
// - iterations: until `probability` of having drawn an all-inlier sample, for an
//   inlier ratio of max(best count, min_inliers) / n, at most max_iterations;
// - result: Horn refitted on all inliers of the best hypothesis (repeated while
//   the inlier set grows), accepted when it has at least min_inliers inliers.
//
// Differences from ORB-SLAM: ORB-SLAM stops at the first hypothesis with more
// than min_inliers inliers and returns it without refit, scores against the
// reprojected map points rather than the keypoints, and uses the asymmetric scale.
// Sampling uses a seeded generator owned by the solver: runs are reproducible.
#include <Eigen/Core>
#include <cstdint>
#include <random>
#include <vector>

#include "core/camera/camera.h"
#include "core/geometry/sim3.h"
#include "core/optimization/sim3_match.h"

namespace orbatlas {

struct Sim3SolverOptions {
  double probability = 0.99;  // wanted probability of drawing one all-inlier sample
  int min_inliers = 20;       // ORB-SLAM2's loop closing (ORB-SLAM3 uses 15-20)
  int max_iterations = 300;   // ORB-SLAM's cap
  bool fix_scale = false;     // true for stereo / RGB-D (scale 1, SE3)
  double chi2 = 9.210;        // per image, times the keypoint's level sigma^2
  std::uint64_t seed = 1;

  // Throws Error naming the first value out of range.
  void check() const;
};

struct Sim3SolverResult {
  bool success = false;               // inlier_count >= min_inliers
  Sim3 S_1_2;                         // p_c1 = S_1_2 * p_c2; identity when no hypothesis was found
  std::vector<std::uint8_t> inliers;  // per match: 1 inlier, 0 outlier
  int inlier_count = 0;
  int iterations = 0;  // RANSAC iterations run
};

// Incremental form (ORB-SLAM's iterate(k)): loop closing can interleave several
// candidate keyframes, a few iterations each. The cameras are not owned and must
// outlive the solver.
class Sim3Solver {
 public:
  // Throws Error on a non-positive or non-finite level sigma2 or bad options.
  Sim3Solver(std::vector<Sim3Match> matches, const Camera& camera1, const Camera& camera2,
             const Sim3SolverOptions& options = {});

  // Runs at most `iterations` more iterations. Returns true when the search is
  // over: the iteration budget is used up, or fewer matches than min_inliers.
  bool iterate(int iterations);
  bool finished() const { return iterations_ >= needed_; }
  int iterations() const { return iterations_; }
  int best_inlier_count() const { return best_count_; }

  // The refitted best hypothesis so far (the final one once finished()).
  Sim3SolverResult result() const;

  // 1 when match i fits S_1_2 in both images (the inlier test above).
  int classify(const Sim3& S_1_2, std::vector<std::uint8_t>* inliers) const;

 private:
  bool inlier(const Sim3Match& m, const Sim3& S_1_2, const Sim3& S_2_1) const;
  void update_needed();

  std::vector<Sim3Match> matches_;
  const Camera* camera1_;  // not owned
  const Camera* camera2_;  // not owned
  Sim3SolverOptions options_;
  std::mt19937_64 rng_;
  int iterations_ = 0;
  int needed_ = 0;  // iterations wanted (adaptive)
  int best_count_ = 0;
  Sim3 best_;
};

// Runs the solver to the end.
Sim3SolverResult solve_sim3_ransac(std::vector<Sim3Match> matches, const Camera& camera1, const Camera& camera2,
                                   const Sim3SolverOptions& options = {});

}  // namespace orbatlas
