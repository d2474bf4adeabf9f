// Map model: covisibility weights and edges, the spanning tree reattached
// when a keyframe is culled, culled objects leaving the map at once, and the
// inertial chain joined over a culled keyframe.
#include <gtest/gtest.h>

#include <algorithm>
#include <memory>
#include <numeric>
#include <random>
#include <set>
#include <vector>

#include "core/common/error.h"
#include "core/map/atlas.h"
#include "tests/support/map_keyframes.h"

namespace orbatlas {
namespace {

using test::keyframe_data;

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

}  // namespace
}  // namespace orbatlas
