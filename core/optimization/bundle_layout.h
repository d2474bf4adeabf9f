#pragma once
// How solve_bundle_levenberg (bundle_levenberg.h) lays out a bundle problem's
// unknowns: which keyframe poses are free, the points the active edges observe
// (eliminated, their edges grouped by point), and where each extra term's
// blocks (a pose's rotation or translation, a velocity, a bias) sit in the
// reduced system. The solver's own; no other user.
#include <Eigen/Core>
#include <cstddef>
#include <vector>

#include "core/optimization/bundle_problem.h"

namespace orbatlas {

constexpr int kNoBundleVar = -1;  // not among the unknowns (fixed or constant)

// A parameter block of an extra term (an inertial edge, a bias walk, a prior)
// placed among the unknowns of the reduced system.
struct BundleTermBlock {
  int offset = -1;       // its first unknown in the reduced system; -1: constant
  int size = 0;          // its unknowns (a quaternion's tangent: 3)
  int global = 0;        // its values (a quaternion: 4)
  int rotation_of = -1;  // the pose var whose rotation it is (through the quaternion's manifold), or -1
};

// The unknowns: the free poses (6 each: rotation, translation) of the active
// edges and the extra terms, then the extra terms' free blocks, which with the
// poses make the reduced system; the points of the active edges, eliminated.
// The active edges are grouped by point (the elimination visits one point's
// edges together).
struct BundleLayout {
  std::vector<int> pose_var;                        // per keyframe: index among the free poses, or kNoBundleVar
  std::vector<std::size_t> free_keyframes;          // pose var -> keyframe
  std::vector<std::size_t> points;                  // point var -> point
  std::vector<std::size_t> point_begin;             // point var -> its first edge; one past the last at the end
  std::vector<std::size_t> edges;                   // active edges (indices into BundleProblem::edges)
  std::vector<int> edge_pose;                       // per entry of `edges`: its pose var, or kNoBundleVar
  std::vector<std::vector<BundleTermBlock>> terms;  // per extra term, per block
  std::vector<std::size_t> free_extras;  // extra blocks (into BundleProblem::extra_blocks) among the unknowns
  std::vector<int> extra_offset;         // per entry of free_extras: its first unknown
  Eigen::Index dim = 0;                  // unknowns of the reduced system
  Eigen::Index pose_dim() const { return static_cast<Eigen::Index>(6 * free_keyframes.size()); }
};

// Throws Error when an extra term's block is neither a keyframe's pose nor
// one of the problem's extra blocks.
BundleLayout bundle_layout_of(const BundleProblem& problem);

}  // namespace orbatlas
