#pragma once
// Relocalisation of a frame against every map of the atlas (ORB-SLAM's
// Relocalization with MLPnP replaced by P3P-RANSAC on bearings): bag-of-words
// candidates from the keyframe index, BoW matching, PnP-RANSAC on bearing vectors
// (camera-model agnostic), pose-only optimisation, then a guided search in the
// candidate's local map when too few inliers remain. The best few candidates
// that fail alone are tried once more with their covisible keyframes' matches
// added (a viewpoint the bag of words links to no single keyframe well).
#include <functional>
#include <memory>
#include <optional>

#include "core/map/keyframe_index.h"
#include "core/estimators/pnp_ransac.h"
#include "core/tracking/frame.h"
#include "core/tracking/frame_camera.h"
#include "core/vocabulary/vocabulary.h"

namespace orbatlas {

struct RelocalizationOptions {
  std::size_t max_candidates = 10;
  int min_bow_matches = 15;
  float bow_ratio = 0.75f;  // best / second-best descriptor distance (ORB-SLAM's)
  // The first `window_candidates` candidates that do not give a pose alone are
  // tried again matched together with their best `window_covisibles`.
  std::size_t window_candidates = 3;
  std::size_t window_covisibles = 5;
  int min_inliers = 50;  // after optimisation (ORB-SLAM's threshold)
  float guided_radius = 10.0f;
  PnpRansacOptions pnp;
  std::optional<MapId> only_map;  // restrict to one map
  // When set, candidates of maps it refuses are skipped (the server keeps a
  // session out of maps another live session is working in).
  std::function<bool(MapId)> may_enter;

  // Throws Error naming the first value out of range.
  void check() const;
};

struct RelocalizationResult {
  bool success = false;
  std::shared_ptr<KeyFrame> keyframe;  // the candidate that worked
  MapId map = 0;
  Pose3 T_w_b;
  int inliers = 0;
  std::size_t candidates = 0;  // tried
  std::size_t windows = 0;     // of them, tried again with their covisibles
};

// On success the frame holds the pose (T_w_b) and its map-point associations.
// `frame.bow` is computed with `vocabulary` when empty.
RelocalizationResult relocalize(Frame& frame, const Vocabulary& vocabulary, const KeyframeIndex& index,
                                const FrameCamera& cam, const Pose3& T_b_c, const RelocalizationOptions& options = {});

}  // namespace orbatlas
