// Map model: ids, atlases side by side, covisibility, spanning tree, culling.
#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>
#include <random>
#include <set>
#include <thread>

#include "core/common/error.h"
#include "core/map/atlas.h"

namespace orbatlas {
namespace {

KeyFrameData keyframe_data(std::size_t slots, const std::vector<int>& levels = {}) {
  KeyFrameData data;
  data.features.keypoints.resize(slots);
  for (std::size_t i = 0; i < slots && i < levels.size(); ++i) data.features.keypoints[i].level = levels[i];
  return data;
}

TEST(MapModel, IdsAreUniqueAcrossTheMapsOfAnAtlas) {
  Atlas atlas;
  EXPECT_EQ(atlas.active_map(), nullptr);
  const std::vector<std::shared_ptr<Map>> maps = {atlas.create_map(), atlas.create_map(), atlas.create_map()};
  EXPECT_EQ(atlas.active_map(), maps[2]);
  std::set<MapId> map_ids;
  std::set<KeyframeId> kf_ids;
  std::set<MapPointId> mp_ids;
  for (const auto& m : maps) map_ids.insert(m->id());
  for (int i = 0; i < 60; ++i) {
    const auto& m = maps[static_cast<std::size_t>(i) % maps.size()];
    kf_ids.insert(m->new_keyframe(keyframe_data(4))->id());
    mp_ids.insert(m->new_map_point({})->id());
  }
  EXPECT_EQ(map_ids.size(), 3u);
  EXPECT_EQ(kf_ids.size(), 60u);
  EXPECT_EQ(mp_ids.size(), 60u);
  for (const auto& m : maps) EXPECT_EQ(m->keyframe_count(), 20u);
  atlas.set_active(maps[0]->id());
  EXPECT_EQ(atlas.active_map(), maps[0]);
  EXPECT_EQ(atlas.map(maps[1]->id()), maps[1]);
  EXPECT_THROW(atlas.set_active(12345), Error);
  EXPECT_EQ(atlas.maps().size(), 3u);
  // An object of one map cannot be added to another.
  auto kf = KeyFrame::create(1000, maps[1]->id(), keyframe_data(1), atlas.counters());
  EXPECT_THROW(maps[0]->add_keyframe(kf), Error);
  EXPECT_THROW(maps[1]->add_keyframe(maps[1]->keyframes().front()), Error);  // duplicate id
}

TEST(MapModel, IdAllocatorCanBeReseeded) {
  IdAllocator ids;
  EXPECT_EQ(ids.next_keyframe_id(), 0u);
  ids.ensure_above(IdKind::keyframe, 41);
  EXPECT_EQ(ids.next_keyframe_id(), 42u);
  ids.ensure_above(IdKind::keyframe, 10);  // never goes back
  EXPECT_EQ(ids.next_keyframe_id(), 43u);
  EXPECT_EQ(ids.next_map_point_id(), 0u);  // kinds are independent
  EXPECT_EQ(ids.next_map_id(), 0u);
  EXPECT_EQ(ids.peek(IdKind::map), 1u);
}

// Replicas of one database: each hands out ids from its own range,
// and ids it loads from the others' ranges never move its counter.
TEST(MapModel, AConfinedAllocatorStaysInItsRange) {
  IdAllocator ids;
  ids.ensure_above(IdKind::map, 5);  // loaded before confining
  ids.confine(IdKind::map, 100, 103);
  EXPECT_EQ(ids.peek(IdKind::map), 100u);
  ids.ensure_above(IdKind::map, 500);  // another writer's, above the range
  ids.ensure_above(IdKind::map, 7);    // and below it
  EXPECT_EQ(ids.next_map_id(), 100u);
  ids.ensure_above(IdKind::map, 101);  // its own, loaded again
  EXPECT_EQ(ids.next_map_id(), 102u);
  EXPECT_THROW(ids.next_map_id(), Error);  // the range is used up
  EXPECT_EQ(ids.next_keyframe_id(), 0u);   // other kinds are not confined
  IdAllocator again;
  again.ensure_above(IdKind::keyframe, 150);  // ids of its range already handed out
  again.confine(IdKind::keyframe, 100, 200);
  EXPECT_EQ(again.next_keyframe_id(), 151u);
  EXPECT_THROW(again.confine(IdKind::keyframe, 5, 5), Error);
}

TEST(MapModel, TwoAtlasesInOneProcessAreIndependent) {
  struct Result {
    std::vector<KeyframeId> kf_ids;
    std::vector<MapPointId> mp_ids;
    CounterSnapshot kfs, mps;
  };
  auto run = [](int n, Result& result) {
    Atlas atlas;
    auto map = atlas.create_map();
    for (int i = 0; i < n; ++i) {
      auto kf = map->new_keyframe(keyframe_data(8));
      auto mp = map->new_map_point({});
      kf->add_observation(0, mp);
      result.kf_ids.push_back(kf->id());
      result.mp_ids.push_back(mp->id());
    }
    for (int i = 0; i < n; i += 2) map->cull_keyframe(result.kf_ids[static_cast<std::size_t>(i)]);
    result.kfs = atlas.counters()->keyframes();
    result.mps = atlas.counters()->map_points();
  };
  Result a, b;
  std::thread ta(run, 500, std::ref(a));
  std::thread tb(run, 300, std::ref(b));
  ta.join();
  tb.join();
  for (std::size_t i = 0; i < a.kf_ids.size(); ++i) EXPECT_EQ(a.kf_ids[i], i);  // each atlas counts from 0
  for (std::size_t i = 0; i < b.kf_ids.size(); ++i) EXPECT_EQ(b.kf_ids[i], i);
  for (std::size_t i = 0; i < b.mp_ids.size(); ++i) EXPECT_EQ(b.mp_ids[i], i);
  EXPECT_EQ(a.kfs.created, 500u);
  EXPECT_EQ(a.kfs.culled, 250u);
  EXPECT_EQ(a.kfs.reclaimed, 250u);
  EXPECT_EQ(b.kfs.created, 300u);
  EXPECT_EQ(b.kfs.culled, 150u);
  EXPECT_EQ(b.kfs.reclaimed, 150u);
  EXPECT_EQ(a.mps.created, 500u);
  EXPECT_EQ(b.mps.created, 300u);
  EXPECT_EQ(b.mps.reclaimed, 0u);  // the atlas was still alive when read
}

TEST(MapModel, CovisibilityKeepsStrongEdgesOrTheBestOne) {
  Atlas atlas;
  auto map = atlas.create_map();
  auto A = map->new_keyframe(keyframe_data(100));
  auto B = map->new_keyframe(keyframe_data(100));
  auto C = map->new_keyframe(keyframe_data(100));
  auto D = map->new_keyframe(keyframe_data(100));
  std::size_t slot_a = 0, slot_b = 0, slot_c = 0, slot_d = 0;
  auto share = [&](int n, std::shared_ptr<KeyFrame>& x, std::size_t& sx, std::shared_ptr<KeyFrame>& y,
                   std::size_t& sy) {
    for (int i = 0; i < n; ++i) {
      auto mp = map->new_map_point({});
      ASSERT_TRUE(x->add_observation(sx++, mp));
      ASSERT_TRUE(y->add_observation(sy++, mp));
    }
  };
  share(20, A, slot_a, B, slot_b);
  share(16, A, slot_a, C, slot_c);
  share(5, A, slot_a, D, slot_d);
  share(2, B, slot_b, D, slot_d);

  A->update_connections();  // B 20, C 16; D (5) is below 15
  ASSERT_EQ(A->connections().size(), 2u);
  EXPECT_EQ(A->connections()[0].keyframe, B->id());
  EXPECT_EQ(A->connections()[0].weight, 20);
  EXPECT_EQ(A->connections()[1].keyframe, C->id());
  EXPECT_EQ(A->connections()[1].weight, 16);
  EXPECT_EQ(B->weight(A->id()), 20);  // mirrored
  EXPECT_EQ(C->weight(A->id()), 16);
  EXPECT_EQ(A->weight(D->id()), 0);

  D->update_connections();  // nothing >= 15: keeps only the best (A, 5), mirrored in A
  ASSERT_EQ(D->connections().size(), 1u);
  EXPECT_EQ(D->connections()[0].keyframe, A->id());
  EXPECT_EQ(D->connections()[0].weight, 5);
  EXPECT_EQ(A->weight(D->id()), 5);
  EXPECT_EQ(B->weight(D->id()), 0);
  const auto best = A->best_covisibles(2);
  ASSERT_EQ(best.size(), 2u);
  EXPECT_EQ(best[0], B);
  EXPECT_EQ(best[1], C);
}

TEST(MapModel, CovisibilityWeightsEqualSharedPointsOnARandomMap) {
  Atlas atlas;
  auto map = atlas.create_map();
  std::mt19937 rng(7);
  const int n_kf = 15, n_mp = 300, n_slots = 150;
  std::vector<std::shared_ptr<KeyFrame>> kfs;
  std::vector<std::shared_ptr<MapPoint>> mps;
  for (int i = 0; i < n_mp; ++i) mps.push_back(map->new_map_point({}));
  std::vector<std::set<std::size_t>> seen(n_kf);  // map point indices per keyframe
  for (int k = 0; k < n_kf; ++k) {
    kfs.push_back(map->new_keyframe(keyframe_data(n_slots)));
    std::vector<std::size_t> order(n_mp);
    std::iota(order.begin(), order.end(), 0);
    std::shuffle(order.begin(), order.end(), rng);
    const int n_obs = std::uniform_int_distribution<int>(20, n_slots)(rng);
    for (int s = 0; s < n_obs; ++s) {
      ASSERT_TRUE(kfs.back()->add_observation(static_cast<std::size_t>(s), mps[order[static_cast<std::size_t>(s)]]));
      seen[static_cast<std::size_t>(k)].insert(order[static_cast<std::size_t>(s)]);
    }
  }
  for (const auto& kf : kfs) kf->update_connections(1);
  for (int i = 0; i < n_kf; ++i) {
    const auto& edges = kfs[static_cast<std::size_t>(i)]->connections();
    for (std::size_t e = 1; e < edges.size(); ++e) {
      EXPECT_TRUE(edges[e - 1].weight > edges[e].weight ||
                  (edges[e - 1].weight == edges[e].weight && edges[e - 1].keyframe < edges[e].keyframe));
    }
    for (int j = 0; j < n_kf; ++j) {
      if (i == j) continue;
      int shared = 0;
      for (std::size_t p : seen[static_cast<std::size_t>(i)])
        shared += static_cast<int>(seen[static_cast<std::size_t>(j)].count(p));
      EXPECT_EQ(kfs[static_cast<std::size_t>(i)]->weight(kfs[static_cast<std::size_t>(j)]->id()), shared)
          << i << " " << j;
    }
  }
}

TEST(MapModel, CullingReattachesSpanningTreeChildren) {
  Atlas atlas;
  auto map = atlas.create_map();
  auto A = map->new_keyframe(keyframe_data(1));
  auto B = map->new_keyframe(keyframe_data(1));
  auto C = map->new_keyframe(keyframe_data(1));
  auto D = map->new_keyframe(keyframe_data(1));
  auto E = map->new_keyframe(keyframe_data(1));
  B->set_parent(A);
  C->set_parent(B);
  D->set_parent(B);
  E->set_parent(B);
  auto link = [](const std::shared_ptr<KeyFrame>& x, const std::shared_ptr<KeyFrame>& y, int w) {
    x->add_connection(y, w);
    y->add_connection(x, w);
  };
  link(C, A, 30);  // C goes to A first,
  link(D, C, 20);  // then D to the reattached C (not to A),
  link(D, B, 50);  // (links to the culled keyframe do not count)
  // and E, covisible with no candidate, to A.
  ASSERT_TRUE(map->cull_keyframe(B->id()));
  EXPECT_EQ(C->parent(), A);
  EXPECT_EQ(D->parent(), C);
  EXPECT_EQ(E->parent(), A);
  EXPECT_EQ(A->child_ids(), (std::vector<KeyframeId>{C->id(), E->id()}));
  EXPECT_EQ(C->child_ids(), (std::vector<KeyframeId>{D->id()}));
  EXPECT_TRUE(B->child_ids().empty());
  EXPECT_EQ(B->parent_id(), A->id());  // kept for chaining relative poses
  EXPECT_EQ(D->weight(B->id()), 0);

  // Culling the root makes its children roots.
  ASSERT_TRUE(map->cull_keyframe(A->id()));
  EXPECT_EQ(C->parent(), nullptr);
  EXPECT_EQ(E->parent(), nullptr);
  EXPECT_EQ(D->parent(), C);
}

TEST(MapModel, CulledObjectsVanishFromTheMapAtOnce) {
  Atlas atlas;
  auto map = atlas.create_map();
  std::vector<std::shared_ptr<KeyFrame>> kfs;
  for (int i = 0; i < 3; ++i) kfs.push_back(map->new_keyframe(keyframe_data(30)));
  std::vector<std::shared_ptr<MapPoint>> mps;
  for (int p = 0; p < 20; ++p) {
    mps.push_back(map->new_map_point({}));
    for (auto& kf : kfs) ASSERT_TRUE(kf->add_observation(static_cast<std::size_t>(p), mps.back()));
  }
  for (auto& kf : kfs) kf->update_connections();
  kfs[1]->set_parent(kfs[0]);
  kfs[2]->set_parent(kfs[1]);
  kfs[0]->add_loop_edge(kfs[2]);
  EXPECT_EQ(kfs[2]->loop_edge_ids(), std::vector<KeyframeId>{kfs[0]->id()});
  EXPECT_EQ(mps[0]->reference_keyframe(), kfs[0]);

  const KeyframeId gone = kfs[1]->id();
  ASSERT_TRUE(map->cull_keyframe(gone));
  EXPECT_FALSE(map->cull_keyframe(gone));
  EXPECT_EQ(map->keyframe(gone), nullptr);
  EXPECT_EQ(map->keyframe_count(), 2u);
  for (const auto& kf : map->keyframes()) EXPECT_NE(kf->id(), gone);
  EXPECT_TRUE(kfs[1]->is_bad());
  EXPECT_EQ(kfs[1]->map_point_count(), 0);
  EXPECT_TRUE(kfs[1]->connections().empty());
  EXPECT_EQ(kfs[0]->weight(gone), 0);
  EXPECT_EQ(kfs[0]->weight(kfs[2]->id()), 20);
  EXPECT_EQ(kfs[2]->parent(), kfs[0]);
  for (const auto& mp : mps) {
    EXPECT_EQ(mp->observation_count(), 2u);
    EXPECT_FALSE(mp->slot_in(gone).has_value());
  }
  EXPECT_FALSE(kfs[1]->add_observation(25, mps[0]));  // a culled keyframe takes nothing new

  const MapPointId mp_gone = mps[0]->id();
  ASSERT_TRUE(map->cull_map_point(mp_gone));
  EXPECT_EQ(map->map_point(mp_gone), nullptr);
  EXPECT_EQ(map->map_point_count(), 19u);
  EXPECT_TRUE(mps[0]->is_bad());
  EXPECT_EQ(mps[0]->observation_count(), 0u);
  EXPECT_EQ(mps[0]->reference_keyframe(), nullptr);
  EXPECT_EQ(kfs[0]->map_point(0), nullptr);
  EXPECT_EQ(kfs[0]->map_point_count(), 19);
  EXPECT_FALSE(kfs[0]->add_observation(0, mps[0]));  // nor does a culled point

  // The reference keyframe moves to the next observer when the first one leaves.
  ASSERT_TRUE(map->cull_keyframe(kfs[0]->id()));
  EXPECT_EQ(mps[1]->reference_keyframe(), kfs[2]);
  EXPECT_TRUE(kfs[2]->loop_edge_ids().empty());
}

TEST(MapModel, ObservationRulesAreChecked) {
  Atlas atlas;
  auto map = atlas.create_map();
  auto kf = map->new_keyframe(keyframe_data(3));
  auto mp = map->new_map_point({});
  auto other = map->new_map_point({});
  EXPECT_THROW(kf->add_observation(3, mp), Error);
  ASSERT_TRUE(kf->add_observation(0, mp));
  EXPECT_THROW(kf->add_observation(0, other), Error);  // slot taken
  EXPECT_THROW(kf->add_observation(1, mp), Error);     // already in slot 0
  EXPECT_THROW(kf->replace(1, mp), Error);
  EXPECT_TRUE(kf->replace(0, other));
  EXPECT_EQ(mp->observation_count(), 0u);
  EXPECT_EQ(other->slot_in(kf->id()), 0u);
  EXPECT_EQ(kf->erase_slot(0), other);
  EXPECT_EQ(kf->erase_slot(0), nullptr);
  EXPECT_EQ(kf->map_point_count(), 0);
  KeyFrameData bad = keyframe_data(3);
  bad.depth = {1.0f, 2.0f};
  bad.u_right = {1.0f, 2.0f};
  EXPECT_THROW(map->new_keyframe(bad), Error);
}

// The walk tracking's local map makes over many keyframes: each point once,
// none already seen, and the slots' ids in step with every kind of slot edit.
TEST(MapModel, UnseenMapPointsAreEachPointOnceThroughEverySlotEdit) {
  Atlas atlas;
  auto map = atlas.create_map();
  auto a = map->new_keyframe(keyframe_data(6));
  auto b = map->new_keyframe(keyframe_data(6));
  std::vector<std::shared_ptr<MapPoint>> p;
  for (int i = 0; i < 7; ++i) p.push_back(map->new_map_point({}));
  for (std::size_t i = 0; i < 4; ++i) ASSERT_TRUE(a->add_observation(i, p[i]));  // a: p0 p1 p2 p3
  ASSERT_TRUE(b->add_observation(0, p[2]));                                      // b: p2 p3 p4 p5
  ASSERT_TRUE(b->add_observation(1, p[3]));
  ASSERT_TRUE(b->add_observation(2, p[4]));
  ASSERT_TRUE(b->add_observation(5, p[5]));
  // The edits: a's slot 1 emptied, its slot 0 given another point (p6 for p0),
  // b's slot 5 emptied only if it holds p5 (it does), slot 2 not if it holds p0.
  EXPECT_EQ(a->erase_slot(1), p[1]);
  EXPECT_TRUE(a->replace(0, p[6]));
  b->erase_slot_if_holds(5, p[5]);
  b->erase_slot_if_holds(2, p[0]);
  EXPECT_EQ(b->replace_if_holds(1, p[3], p[1]), SlotEdit::kDone);  // b: p2 p1 p4
  FlatIdSet seen;
  seen.clear();
  seen.insert(p[2]->id());  // the frame's own point
  std::vector<MapPointId> walked;
  for (const auto& kf : {a, b})
    kf->for_each_unseen_map_point(seen, [&](const std::shared_ptr<MapPoint>& mp) { walked.push_back(mp->id()); });
  // a: p6 (slot 0), p3 (slot 3); b: p1, p4 (p2 was seen).
  EXPECT_EQ(walked, (std::vector<MapPointId>{p[6]->id(), p[3]->id(), p[1]->id(), p[4]->id()}));
  walked.clear();
  a->for_each_unseen_map_point(seen, [&](const std::shared_ptr<MapPoint>& mp) { walked.push_back(mp->id()); });
  EXPECT_TRUE(walked.empty());  // all seen now
}

// The inertial chain: each keyframe links to its predecessor with
// the IMU preintegrated between them; culling a keyframe of the chain joins its
// two increments into its successor's link, so the chain skips it and spans the
// same time; culling the chain's first keyframe breaks the chain there.
TEST(MapModel, CullingAKeyframeOfTheInertialChainJoinsItsIncrements) {
  Atlas atlas;
  auto map = atlas.create_map();
  std::vector<std::shared_ptr<KeyFrame>> kfs;
  for (int k = 0; k < 4; ++k) {
    KeyFrameData data = keyframe_data(2);
    data.timestamp_ns = k * 400'000'000LL;
    kfs.push_back(map->new_keyframe(std::move(data)));
  }
  // A constant rotation and acceleration, 0.4 s between keyframes at 200 Hz.
  const auto increments = [](int steps) {
    auto pre = std::make_shared<Preintegration>(ImuBias{}, ImuNoise{});
    for (int i = 0; i < steps; ++i)
      pre->integrate(Eigen::Vector3d(0.1, 0.0, 0.2), Eigen::Vector3d(0.3, 0.0, 9.81), 0.005);
    return pre;
  };
  const Pose3 T_c_i(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.01, 0.02, 0.03));
  for (int k = 1; k < 4; ++k) kfs[k]->set_inertial_link(kfs[k - 1], increments(80), T_c_i);
  EXPECT_EQ(kfs[0]->inertial_next(), kfs[1]);
  ASSERT_TRUE(map->cull_keyframe(kfs[1]->id()));
  const auto joined = kfs[2]->inertial_link();
  ASSERT_TRUE(joined.has_value());
  EXPECT_EQ(joined->previous_id, kfs[0]->id());
  ASSERT_TRUE(joined->T_c_i.has_value());  // the chain's IMU stays where it was
  EXPECT_EQ(joined->T_c_i->t, T_c_i.t);
  EXPECT_EQ(kfs[0]->inertial_next(), kfs[2]);
  const auto whole = increments(160);  // what one link over both would hold
  EXPECT_NEAR(joined->from_previous->dt(), 0.8, 1e-12);
  EXPECT_LT((joined->from_previous->delta_p() - whole->delta_p()).norm(), 1e-12);
  EXPECT_LT((joined->from_previous->delta_v() - whole->delta_v()).norm(), 1e-12);
  // The chain's first keyframe goes: its successor's link goes with it.
  ASSERT_TRUE(map->cull_keyframe(kfs[0]->id()));
  EXPECT_FALSE(kfs[2]->inertial_link().has_value());
  EXPECT_TRUE(kfs[3]->inertial_link().has_value());
  EXPECT_THROW(kfs[3]->set_inertial_link(kfs[3], increments(1), T_c_i), Error);
}

// Changing a map's frame (the gravity alignment of a visual-inertial map):
// every keyframe, point and viewing direction follows, the relative geometry is
// kept, and the frame epoch moves on (a global BA solved before is dropped).
TEST(MapModel, ChangingTheFrameMovesEverythingAndKeepsTheGeometry) {
  Atlas atlas;
  auto map = atlas.create_map();
  auto a = map->new_keyframe(keyframe_data(1));
  auto b = map->new_keyframe(keyframe_data(1));
  a->set_T_w_b(Pose3(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ())), Eigen::Vector3d(1, 2, 3)));
  b->set_T_w_b(Pose3(Eigen::Quaterniond(Eigen::AngleAxisd(-0.2, Eigen::Vector3d::UnitX())), Eigen::Vector3d(0, 1, 0)));
  MapPointData d;
  d.p_w = Eigen::Vector3d(4, 5, 6);
  auto p = map->new_map_point(d);
  p->set_normal(Eigen::Vector3d(0, 0, 1));
  const Pose3 relative = a->T_w_b().inverse() * b->T_w_b();
  const Pose3 T(Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 1, 0).normalized())),
                Eigen::Vector3d::Zero());
  const auto epoch = map->frame_epoch();
  map->change_frame(T);
  EXPECT_EQ(map->frame_epoch(), epoch + 1);
  EXPECT_LT((p->p_w() - T * Eigen::Vector3d(4, 5, 6)).norm(), 1e-12);
  EXPECT_LT((p->normal() - T.q * Eigen::Vector3d(0, 0, 1)).norm(), 1e-12);
  const Pose3 after = a->T_w_b().inverse() * b->T_w_b();
  EXPECT_LT((after.t - relative.t).norm(), 1e-12);
  EXPECT_LT(after.q.angularDistance(relative.q), 1e-12);
}

// Rescaling a map (a monocular map made metric by its IMU): positions, point
// distances, IMU velocities and culled keyframes' anchors scale; rotations and
// viewing directions stay; the keyframes' units accumulate and the epoch moves on.
TEST(MapModel, RescalingScalesPositionsDistancesVelocitiesAndAnchors) {
  Atlas atlas;
  auto map = atlas.create_map();
  auto a = map->new_keyframe(keyframe_data(1));
  auto b = map->new_keyframe(keyframe_data(1));
  auto c = map->new_keyframe(keyframe_data(1));
  const Eigen::Quaterniond qa(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()));
  a->set_T_w_b(Pose3(qa, Eigen::Vector3d(1, 2, 3)));
  b->set_T_w_b(Pose3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 1, 0)));
  c->set_T_w_b(Pose3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 2, 0)));
  c->set_parent(b);
  a->set_imu_state(KeyFrame::ImuState{Eigen::Vector3d(0.1, 0.2, 0.3), {}});
  MapPointData d;
  d.p_w = Eigen::Vector3d(4, 5, 6);
  auto p = map->new_map_point(d);
  p->set_normal(Eigen::Vector3d(0, 0, 1));
  p->set_distances(1.0f, 8.0f);
  ASSERT_TRUE(map->cull_keyframe(c->id()));  // anchored to b: 1 m along y
  const auto epoch = map->frame_epoch();
  map->rescale(2.5);
  map->rescale(2.0);
  EXPECT_DOUBLE_EQ(a->units(), 5.0);
  EXPECT_DOUBLE_EQ(map->keyframe_placement(c->id())->units, 5.0);  // culled: through b
  EXPECT_EQ(map->frame_epoch(), epoch + 2);
  EXPECT_LT((a->T_w_b().t - Eigen::Vector3d(5, 10, 15)).norm(), 1e-12);
  EXPECT_LT(a->T_w_b().q.angularDistance(qa), 1e-12);
  EXPECT_LT((a->imu_state()->v_i - Eigen::Vector3d(0.5, 1.0, 1.5)).norm(), 1e-12);
  EXPECT_LT((p->p_w() - Eigen::Vector3d(20, 25, 30)).norm(), 1e-12);
  EXPECT_LT((p->normal() - Eigen::Vector3d(0, 0, 1)).norm(), 1e-12);
  EXPECT_FLOAT_EQ(p->min_distance(), 5.0f);
  EXPECT_FLOAT_EQ(p->max_distance(), 40.0f);
  const auto culled = map->keyframe_pose(c->id());
  ASSERT_TRUE(culled.has_value());
  EXPECT_LT((culled->t - Eigen::Vector3d(0, 10, 0)).norm(), 1e-12);  // b at 5, and 5 m on
  EXPECT_THROW(map->rescale(0.0), Error);
  EXPECT_THROW(map->rescale(std::nan("")), Error);
}

// A map is metric once it holds a keyframe with measured depths (stereo,
// RGB-D) or is inertial; monocular keyframes (depths all -1) leave it free.
TEST(MapModel, AMapIsMetricWithAKeyframeOfMeasuredDepthOrAnImu) {
  Atlas atlas;
  auto map = atlas.create_map();
  EXPECT_FALSE(map->metric_scale());  // empty
  KeyFrameData mono = keyframe_data(3);
  mono.depth.assign(3, -1.0f);
  mono.u_right.assign(3, -1.0f);
  EXPECT_FALSE(map->new_keyframe(mono)->has_depth());
  EXPECT_FALSE(map->metric_scale());
  map->set_inertial_state(Map::InertialState{});
  EXPECT_TRUE(map->metric_scale());

  auto stereo_map = atlas.create_map();
  map->new_keyframe(keyframe_data(2));  // no stereo vectors at all
  KeyFrameData stereo = mono;
  stereo.depth[1] = 2.5f;
  stereo.u_right[1] = 300.0f;
  const auto kf = stereo_map->new_keyframe(stereo);
  EXPECT_TRUE(kf->has_depth());
  EXPECT_TRUE(stereo_map->metric_scale());
}

// Frame anchors are stored in their keyframe's units, culled anchors in their
// parent's: a later change of scale about a keyframe (a Sim(3) loop moving
// it, a rescale of the map) moves and scales what hangs from it, exactly.
TEST(MapModel, AnchorsFollowTheirKeyframesUnitsThroughCulledParents) {
  Atlas atlas;
  auto map = atlas.create_map();
  auto a = map->new_keyframe(keyframe_data(1));
  auto b = map->new_keyframe(keyframe_data(1));
  a->set_T_w_b(Pose3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(1, 0, 0)));
  b->set_T_w_b(Pose3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(1, 2, 0)));
  b->set_parent(a);
  b->scale_units(2.0);  // b's neighbourhood was scaled once already
  // A frame 4 along z from b, stored as tracking stores it: divided by b's units.
  const FrameAnchor frame{1, map->id(), b->id(), Pose3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, 2))};
  const auto at = [&] { return atlas.frame_pose(frame).value().t; };
  EXPECT_LT((at() - Eigen::Vector3d(1, 2, 4)).norm(), 1e-12);
  ASSERT_TRUE(map->cull_keyframe(b->id()));
  EXPECT_LT((at() - Eigen::Vector3d(1, 2, 4)).norm(), 1e-12);  // through a now
  EXPECT_DOUBLE_EQ(map->keyframe_placement(b->id())->units, 2.0);

  // A Sim(3) correction about a: moved to the origin, lengths about it x3.
  a->set_T_w_b(Pose3());
  a->scale_units(3.0);
  EXPECT_LT((map->keyframe_pose(b->id())->t - Eigen::Vector3d(0, 6, 0)).norm(), 1e-12);
  EXPECT_DOUBLE_EQ(map->keyframe_placement(b->id())->units, 6.0);
  EXPECT_LT((at() - Eigen::Vector3d(0, 6, 12)).norm(), 1e-12);
  // The whole map halved.
  map->rescale(0.5);
  EXPECT_LT((at() - Eigen::Vector3d(0, 3, 6)).norm(), 1e-12);
  EXPECT_THROW(a->scale_units(0.0), Error);
  EXPECT_THROW(a->set_units(-1.0), Error);
}

}  // namespace
}  // namespace orbatlas
