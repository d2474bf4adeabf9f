#pragma once
// Merging two maps of the atlas that place recognition found to share a place
// (ORB-SLAM3's map merging):
//  1. the source map (the one holding `current`) is moved whole into the
//     target map (holding `matched`), every pose and point transformed by the
//     transform the place match measured (a similarity when the source's scale
//     is free: a monocular map takes the target's scale, e.g. a stereo map's
//     metric one, and so does a monocular-inertial map whose scale has not
//     settled, LoopCloserOptions::settled_inertial_refinements); the source
//     map leaves the atlas;
//  2. the spanning trees are joined: the path from `current` to its old root
//     is reversed and `current` becomes a child of `matched`;
//  3. the matched window's points are fused into `current` and its covisible
//     keyframes (duplicates merged, new observations), which links the two
//     parts by covisibility, plus a loop edge current <-> matched.
// A global bundle adjustment afterwards (the caller's choice) refines the
// joined map. Holds the atlas's maps lock exclusively while it edits; the
// caller makes sure no tracking or mapping works in either map.
#include "core/loop/place_match.h"
#include "core/map/atlas.h"
#include "core/tracking/frame_camera.h"

namespace orbatlas {

struct MapMergeOptions {
  float fusion_th = 4.0f;  // ORB-SLAM's SearchAndFuse radius (pixels x scale)

  // Throws Error naming the first value out of range.
  void check() const;
};

struct MapMergeStats {
  MapId source = 0, target = 0;
  std::size_t keyframes_moved = 0, points_moved = 0;
  std::size_t observations_fused = 0, points_fused = 0, new_links = 0;
  bool four_dof = false;  // two inertial maps: the source turned about z and moved only
  double scale = 1.0;     // the source's lengths were multiplied by it (a map of free scale)
  double ms = 0.0;
};

// Whether `source` may be merged into `target`: the merge moves the source
// into the target's units, so a metric map (Map::metric_scale) never goes into
// one of free scale (a monocular map); that map may join it from its own side.
bool merge_keeps_scale(const Map& source, const Map& target);

// Whether a merge of `source`, a single camera's map (`single_camera`), is
// estimated as a similarity taking the target's scale: the map is of free
// scale, or made metric by its IMU but with fewer than `settled_refinements`
// inertial refinements (LoopCloserOptions::settled_inertial_refinements) and
// no measured depth. A stereo or RGB-D session's map: never.
bool merges_in_sim3(const Map& source, bool single_camera, std::size_t settled_refinements);

// Throws Error when the match is within one map or a map is missing.
MapMergeStats merge_maps(Atlas& atlas, const PlaceMatch& match, const FrameCamera& cam,
                         const MapMergeOptions& options = {});

}  // namespace orbatlas
