#pragma once
// GTest comparisons of every field of two atlases (an original and what was
// loaded back), and counts.
#include <cstddef>
#include <string>

#include "core/map/atlas.h"

namespace orbatlas::test {

void expect_pose_eq(const Pose3& a, const Pose3& b, const std::string& what);  // bit for bit
// `same_bow`: b's BoW vectors equal a's; otherwise b has none (loaded without vocabulary).
void expect_keyframe_eq(const Map& map_a, const KeyFrame& a, const KeyFrame& b, bool same_bow);
void expect_point_eq(const MapPoint& a, const MapPoint& b);
// The culled keyframes' anchors, and keyframe_pose of each culled id, bit for bit.
void expect_culled_eq(const Map& a, const Map& b);
// Maps, keyframes, points, culled anchors, active map and id allocator.
// Inertial state and every keyframe's inertial link (maps with the same keyframes).
void expect_inertial_eq(const Map& a, const Map& b);
// One map: its keyframes, points, culled keyframes and inertial state.
void expect_map_eq(const Map& a, const Map& b, bool same_bow);
void expect_atlas_eq(const Atlas& a, const Atlas& b, bool same_bow);

std::size_t count_keyframes(const Atlas& atlas);
std::size_t count_points(const Atlas& atlas);
std::size_t count_culled_keyframes(const Atlas& atlas);

}  // namespace orbatlas::test
