#pragma once
// The whole evaluation of an estimated trajectory against ground truth:
// associate -> align -> ATE and RPE (what `orbatlas eval` reports).
#include <cstddef>
#include <optional>
#include <utility>
#include <vector>

#include "core/eval/alignment.h"
#include "core/eval/association.h"
#include "core/eval/metrics.h"
#include "core/eval/segment_errors.h"

namespace orbatlas {

struct EvalOptions {
  AlignMode align = AlignMode::kSe3;
  AssociationOptions association;
  TimestampNs rpe_delta_ns = 1'000'000'000;  // RPE over 1 s
  // The time spans the estimate should cover (coverage; several for sessions
  // evaluated together); empty: the ground truth's first to last pose.
  // `orbatlas eval` passes each dataset's camera frames.
  std::vector<std::pair<TimestampNs, TimestampNs>> spans;
  // The estimate is of a frame attached to the body (a single camera that
  // maps reports its camera's poses): the ground truth's body poses are moved
  // to it (T_w_b * T_b_x) before they are compared. None: the body's.
  std::optional<Pose3> estimate_T_b_x;
  // KITTI's relative errors over path segments of these lengths (segment_errors.h);
  // empty: the lengths that suit the path (kitti_lengths_for_path); none: not computed.
  std::optional<std::vector<double>> segment_lengths_m;

  // Throws Error naming the first value out of range.
  void check() const;
};

// How much of a time span an estimate covers: the time between consecutive
// estimated poses inside the span, counted where they are at most `max_step_ns`
// apart (a lost stretch counts nothing), over the span's length. A run that
// tracks every frame covers ~1; one that loses half its frames ~0.5.
struct Coverage {
  double fraction = 0.0;  // covered_s / span_s, in [0, 1]
  double covered_s = 0.0, span_s = 0.0;
};
// Several spans add up. max_step_ns 0: three times the estimate's median step
// (at least 1 ms).
Coverage trajectory_coverage(const Trajectory& estimate, const std::vector<std::pair<TimestampNs, TimestampNs>>& spans,
                             TimestampNs max_step_ns = 0);

struct EvalResult {
  AlignMode align = AlignMode::kSe3;
  Similarity3 alignment;  // estimate world -> ground-truth world
  ErrorStats ate;         // position error after alignment [m]
  RpeStats rpe;
  std::size_t matched = 0;              // estimated poses with a ground-truth pose
  std::size_t est_poses = 0;            // all estimated poses
  std::size_t gt_poses = 0;             // all ground-truth poses
  Coverage coverage;                    // of EvalOptions::span (the ground truth's by default)
  std::optional<KittiErrors> segments;  // with EvalOptions::segment_lengths_m
};

// Throws Error when fewer than 3 estimated poses match the ground truth.
EvalResult evaluate_trajectory(const Trajectory& estimate, const Trajectory& ground_truth,
                               const EvalOptions& options = {});

}  // namespace orbatlas
