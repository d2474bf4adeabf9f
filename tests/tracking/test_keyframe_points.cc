// Filling a new keyframe while local mapping edits it (a race local mapping once lost):
// the atomic slot edits and add_keyframe_points, deterministically and under a
// concurrent fusing thread.
#include <gtest/gtest.h>

#include <atomic>
#include <thread>

#include "core/common/error.h"
#include "core/map/atlas.h"
#include "core/map/map_point_update.h"
#include "core/tracking/keyframe_points.h"

namespace orbatlas {
namespace {

constexpr std::size_t kSlots = 40;

KeyFrameData keyframe_data(std::size_t slots) {
  KeyFrameData data;
  data.features.keypoints.resize(slots);
  data.features.descriptors.resize(slots);
  data.depth.assign(slots, 2.0f);
  data.u_right.assign(slots, 100.0f);
  return data;
}

// A frame whose every keypoint has a stereo depth (1 m + 1 cm per index), the
// first `tracked` associated with `points`.
Frame stereo_frame(const std::vector<std::shared_ptr<MapPoint>>& points) {
  Frame frame;
  frame.features.keypoints.resize(kSlots);
  frame.features.descriptors.resize(kSlots);
  for (std::size_t i = 0; i < kSlots; ++i) {
    Keypoint& kp = frame.features.keypoints[i];
    kp.bearing = Eigen::Vector3d(0.01 * static_cast<double>(i), 0.0, 1.0).normalized();
    kp.uv = Eigen::Vector2f(10.0f * static_cast<float>(i), 5.0f);
    kp.uv_undistorted = kp.uv;
  }
  frame.depth.resize(kSlots);
  frame.u_right.resize(kSlots);
  for (std::size_t i = 0; i < kSlots; ++i) {
    frame.depth[i] = 1.0f + 0.01f * static_cast<float>(i);
    frame.u_right[i] = frame.features.keypoints[i].uv.x() - 5.0f;
  }
  frame.map_points.assign(kSlots, nullptr);
  frame.outlier.assign(kSlots, false);
  for (std::size_t i = 0; i < points.size() && i < kSlots; ++i) frame.map_points[i] = points[i];
  frame.has_pose = true;
  return frame;
}

ScalePyramid pyramid() {
  ScalePyramid p;
  p.scale_factor = 1.2;
  p.n_levels = 8;
  return p;
}

// Points observed by an older keyframe (so tracking would count them as mapped).
std::vector<std::shared_ptr<MapPoint>> mapped_points(Map& map, std::size_t n) {
  const auto older = map.new_keyframe(keyframe_data(kSlots));
  std::vector<std::shared_ptr<MapPoint>> points;
  for (std::size_t i = 0; i < n; ++i) {
    MapPointData data;
    data.p_w = Eigen::Vector3d(0.01 * static_cast<double>(i), 0.0, 1.0);
    points.push_back(map.new_map_point(data));
    EXPECT_TRUE(older->add_observation(i, points.back()));
  }
  return points;
}

TEST(SlotEdits, TryAddReportsWhatStoodInTheWayAndChangesNothing) {
  Atlas atlas;
  const auto map = atlas.create_map();
  const auto kf = map->new_keyframe(keyframe_data(3));
  const auto a = map->new_map_point({});
  const auto b = map->new_map_point({});
  EXPECT_EQ(kf->try_add_observation(0, a), SlotEdit::kDone);
  EXPECT_EQ(kf->try_add_observation(0, b), SlotEdit::kSlotTaken);
  EXPECT_EQ(kf->try_add_observation(1, a), SlotEdit::kAlreadyObserved);
  EXPECT_EQ(kf->map_point(0), a);
  EXPECT_EQ(kf->map_point(1), nullptr);
  EXPECT_EQ(kf->map_point_count(), 1);
  EXPECT_EQ(b->observation_count(), 0u);
  ASSERT_TRUE(map->cull_map_point(b->id()));
  EXPECT_EQ(kf->try_add_observation(2, b), SlotEdit::kBad);
  EXPECT_EQ(kf->map_point(2), nullptr);
  // The strict form (single-owner code such as loading) still throws.
  EXPECT_THROW(kf->add_observation(0, map->new_map_point({})), Error);
}

TEST(SlotEdits, ReplaceIfHoldsLeavesASlotAnotherEditChanged) {
  Atlas atlas;
  const auto map = atlas.create_map();
  const auto kf = map->new_keyframe(keyframe_data(2));
  const auto a = map->new_map_point({});
  const auto b = map->new_map_point({});
  const auto c = map->new_map_point({});
  ASSERT_TRUE(kf->add_observation(0, a));
  EXPECT_EQ(kf->replace_if_holds(0, b, c), SlotEdit::kSlotChanged);  // holds a, not b
  EXPECT_EQ(kf->map_point(0), a);
  EXPECT_EQ(c->observation_count(), 0u);
  EXPECT_EQ(kf->replace_if_holds(0, a, c), SlotEdit::kDone);
  EXPECT_EQ(kf->map_point(0), c);
  EXPECT_EQ(a->observation_count(), 0u);
  EXPECT_EQ(*c->slot_in(kf->id()), 0u);
  EXPECT_EQ(kf->map_point_count(), 1);
}

TEST(KeyframePoints, ASlotFusedBetweenTheTwoPassesKeepsTheFusedPoint) {
  // The interleaving that aborted runs: tracking has put the frame's tracked
  // point P in the new keyframe's slot; local mapping, fusing a neighbour, then
  // replaces P by Q in that keyframe and culls P. Tracking's second pass (new
  // points from stereo matches) must take Q, not make a point for a slot that
  // is no longer free.
  Atlas atlas;
  const auto map = atlas.create_map();
  auto points = mapped_points(*map, 2);
  const auto q = map->new_map_point({});
  const auto other = map->new_keyframe(keyframe_data(kSlots));
  ASSERT_TRUE(other->add_observation(5, q));
  Frame frame = stereo_frame(points);
  const auto kf = map->new_keyframe(keyframe_data(kSlots));
  ASSERT_EQ(kf->try_add_observation(0, points[0]), SlotEdit::kDone);  // tracking's first pass
  ASSERT_TRUE(replace_map_point(*map, points[0], q));                 // local mapping's fusion
  ASSERT_TRUE(points[0]->is_bad());
  ASSERT_EQ(kf->map_point(0), q);
  const std::size_t points_before = map->map_point_count();

  KeyframePointsOptions options;
  options.all_stereo_points = true;
  KeyframePointsResult result;
  ASSERT_NO_THROW(result = add_keyframe_points(*map, kf, frame, Pose3{}, pyramid(), options));
  EXPECT_EQ(frame.map_points[0], q);  // the frame follows the fusion
  EXPECT_EQ(kf->map_point(0), q);
  EXPECT_EQ(kf->map_point(1), points[1]);
  EXPECT_EQ(result.observations, 1u);  // points[1]; points[0] was culled
  EXPECT_EQ(result.created, kSlots - 2);
  EXPECT_EQ(map->map_point_count(), points_before + kSlots - 2);
  for (std::size_t i = 0; i < kSlots; ++i) {
    ASSERT_NE(kf->map_point(i), nullptr) << "slot " << i;
    EXPECT_EQ(frame.map_points[i], kf->map_point(i)) << "slot " << i;
  }
  EXPECT_EQ(kf->map_point_count(), static_cast<int>(kSlots));
}

TEST(KeyframePoints, AKeyframeFilledWhileAnotherThreadFusesIntoItStaysConsistent) {
  // Local mapping's fusion hammering the keyframe tracking is filling: it puts
  // its own points in free slots and replaces what tracking put there. Every
  // round must end with slots and observer lists agreeing and no orphan point.
  Atlas atlas;
  const auto map = atlas.create_map();
  std::size_t races = 0;
  for (int round = 0; round < 200; ++round) {
    auto points = mapped_points(*map, kSlots / 2);
    Frame frame = stereo_frame(points);
    const auto kf = map->new_keyframe(keyframe_data(kSlots));
    std::vector<std::shared_ptr<MapPoint>> fusers;
    for (std::size_t i = 0; i < kSlots; ++i) fusers.push_back(map->new_map_point({}));
    std::atomic<bool> go{false};
    std::thread fusion([&] {
      while (!go.load()) std::this_thread::yield();
      for (std::size_t i = kSlots; i-- > 0;) {
        const auto held = kf->map_point(i);
        if (held && !held->is_bad()) {
          replace_map_point(*map, held, fusers[i]);
        } else {
          add_observation_if_free(*kf, i, fusers[i]);
        }
      }
      // Like triangulation: a point that went nowhere is taken out again.
      for (const auto& mp : fusers)
        if (mp->observation_count() == 0) map->cull_map_point(mp->id());
    });
    KeyframePointsOptions options;
    options.all_stereo_points = true;
    go.store(true);
    KeyframePointsResult result;
    EXPECT_NO_THROW(result = add_keyframe_points(*map, kf, frame, Pose3{}, pyramid(), options));
    fusion.join();
    races += result.lost_races;
    for (std::size_t i = 0; i < kSlots; ++i) {
      const auto held = kf->map_point(i);
      ASSERT_NE(held, nullptr) << "round " << round << " slot " << i;
      EXPECT_FALSE(held->is_bad());
      ASSERT_TRUE(held->slot_in(kf->id()).has_value());
      EXPECT_EQ(*held->slot_in(kf->id()), i);
    }
    for (const auto& mp : map->map_points()) EXPECT_GT(mp->observation_count(), 0u) << "an orphan point";
    // Leave the next round a small map.
    for (const auto& mp : map->map_points()) map->cull_map_point(mp->id());
    for (const auto& k : map->keyframes()) map->cull_keyframe(k->id());
  }
  RecordProperty("lost_races", static_cast<int>(races));
}

}  // namespace
}  // namespace orbatlas
