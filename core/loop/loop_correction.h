#pragma once
// Closing a verified loop in one map (ORB-SLAM's LoopClosing::CorrectLoop),
// with local mapping paused:
//  1. the current keyframe and its covisible keyframes (the group) move with the
//     corrected pose of the current keyframe, keeping their relative poses; the
//     points they see keep their position in the camera that corrected them;
//  2. the window's points are fused into the group (duplicates merged, new
//     observations), which creates new covisibility links across the loop;
//  3. essential-graph optimisation over every keyframe of the map (spanning
//     tree, existing loop edges, strong covisibility, and the new loop links),
//     the map's first keyframe fixed; in Sim(3) when the loop's scale is free
//     (a monocular map: the scale drift is spread along the loop), else in
//     SE(3), or yaw and translation for an inertial map; every point follows
//     the keyframe that corrected it or its reference keyframe;
//  4. a loop edge between the current and the matched keyframe.
#include "core/loop/place_match.h"
#include "core/map/map.h"
#include "core/optimization/essential_graph.h"
#include "core/tracking/frame_camera.h"

namespace orbatlas {

struct LoopCorrectionOptions {
  float fusion_th = 4.0f;         // ORB-SLAM's SearchAndFuse radius (pixels x scale)
  int strong_covisibility = 100;  // covisibility edges of the essential graph
  EssentialGraphOptions graph;    // fix_scale and yaw_only are set from the loop and the map

  // Throws Error naming the first value out of range.
  void check() const;
};

struct LoopCorrectionStats {
  std::size_t group_keyframes = 0, corrected_points = 0;
  std::size_t observations_fused = 0, points_fused = 0, new_links = 0;
  std::size_t graph_nodes = 0, graph_edges = 0;
  double correction_m = 0.0;      // translation applied to the current keyframe
  double correction_deg = 0.0;    // rotation applied to the current keyframe
  double correction_scale = 1.0;  // lengths about the current keyframe are multiplied by it (1: metric map)
  bool four_dof = false;          // an inertial map: yaw and translation only
  double graph_ms = 0.0, total_ms = 0.0;
};

LoopCorrectionStats correct_loop(Map& map, const PlaceMatch& loop, const FrameCamera& cam,
                                 const LoopCorrectionOptions& options = {});

}  // namespace orbatlas
