#pragma once
// The whole evaluation of an estimated trajectory against ground truth:
// associate -> align -> ATE and RPE (what `orbatlas eval` reports).
#include <cstddef>

#include "core/eval/alignment.h"
#include "core/eval/association.h"
#include "core/eval/metrics.h"

namespace orbatlas {

struct EvalOptions {
  AlignMode align = AlignMode::kSe3;
  AssociationOptions association;
  TimestampNs rpe_delta_ns = 1'000'000'000;  // RPE over 1 s
};

struct EvalResult {
  AlignMode align = AlignMode::kSe3;
  Similarity3 alignment;  // estimate world -> ground-truth world
  ErrorStats ate;         // position error after alignment [m]
  RpeStats rpe;
  std::size_t matched = 0;    // estimated poses with a ground-truth pose
  std::size_t est_poses = 0;  // all estimated poses
  std::size_t gt_poses = 0;   // all ground-truth poses
};

// Throws Error when fewer than 3 estimated poses match the ground truth.
EvalResult evaluate_trajectory(const Trajectory& estimate, const Trajectory& ground_truth,
                               const EvalOptions& options = {});

}  // namespace orbatlas
