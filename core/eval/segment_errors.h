#pragma once
// The KITTI odometry benchmark's relative errors (Geiger et al., 2012, its
// devkit's evaluate_odometry): from every `step`-th associated pose, the first
// pose at least L metres further along the ground truth's path; the error of
// that relative motion, (gt_i^-1 gt_j)^-1 (est_i^-1 est_j), its translation over
// L (in %) and its rotation angle over L (deg/m), averaged over every segment of
// every length L. Rigid alignments cancel out; `scale` multiplies the
// estimate's translations (the sim3 scale; 1 otherwise).
#include <cstddef>
#include <vector>

#include "core/eval/association.h"

namespace orbatlas {

struct SegmentErrors {
  double length_m = 0.0;
  std::size_t segments = 0;
  double trans_percent = 0.0;  // mean translation error / length, in %
  double rot_deg_per_m = 0.0;  // mean rotation error / length
};

struct KittiErrors {
  std::vector<SegmentErrors> by_length;             // the lengths asked for, in order (segments 0 where none fits)
  std::size_t segments = 0;                         // over all lengths
  double trans_percent = 0.0, rot_deg_per_m = 0.0;  // the means over all segments (the benchmark's figures)
  double path_m = 0.0;                              // the ground truth's path length over the pairs
};

// The benchmark's segment lengths.
std::vector<double> kitti_benchmark_lengths();
// The benchmark's lengths that fit in a path of `path_m`; for a shorter path
// (an excerpt), eight lengths from a tenth to eight tenths of it, in whole metres.
std::vector<double> kitti_lengths_for_path(double path_m);
// The ground truth's path length over the pairs.
double ground_truth_path_length(const std::vector<PosePair>& pairs);

// Throws Error for a length that is not positive or a step of 0.
KittiErrors kitti_relative_errors(const std::vector<PosePair>& pairs, double scale,
                                  const std::vector<double>& lengths_m, std::size_t step = 10);

}  // namespace orbatlas
