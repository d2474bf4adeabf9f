// Merge work shared between the replicas of a PostgreSQL atlas (issue 23,
// core/server/shared_merges.h, core/server/map_ownership.h), on a throwaway
// cluster: a map's merge row is claimed by the replica that owns the map, once;
// put back as it was, or until a retry time (then nobody asks for its map);
// asked for by another replica once it waited;
// a map asked for is handed over and taken like a dead replica's; the rows of
// a replica that stopped go with its maps.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>

#include "core/persistence/pg_schema.h"
#include "core/persistence/wall_clock.h"
#include "core/server/map_ownership.h"
#include "core/server/replica_registry.h"
#include "core/server/shared_merges.h"
#include "tests/throwaway_postgres.h"

namespace orbatlas {
namespace {

using SharedMergeWorkTest = test::PostgresDatabaseTest;

ReplicaOptions long_lease() {
  ReplicaOptions o;
  o.lease_s = 60.0;  // nobody dies of old age during the test
  return o;
}

StoredMerge merge_of(MapId map) { return StoredMerge{map, {"euroc/stereo", ""}, 100 + map, std::nullopt, false}; }

void own(PgDb& db, MapId map, std::uint64_t replica) {
  db.prepare("INSERT INTO map_owners(map_id, replica_id, claimed_ns) VALUES (?1, ?2, 0)")
      .bind_int64(1, static_cast<std::int64_t>(map))
      .bind_int64(2, static_cast<std::int64_t>(replica))
      .run();
}

bool contains(const std::vector<MapId>& maps, MapId map) {
  return std::find(maps.begin(), maps.end(), map) != maps.end();
}

TEST_F(SharedMergeWorkTest, ARowIsClaimedOnceByItsMapsOwnerAndWaitsAgainWhenPutBackOrItsClaimerStops) {
  migrate_postgres_schema(*db_, unix_time_ns());
  const std::string uri = cluster().uri(name_);
  ReplicaRegistry a(uri, long_lease()), b(uri, long_lease());
  const MapId map_a = replica_id_range(a.id(), kReplicaMapIdShift).begin + 1;
  const MapId map_b = replica_id_range(b.id(), kReplicaMapIdShift).begin + 1;
  own(*db_, map_a, a.id());
  own(*db_, map_b, b.id());
  SharedMerges merges(uri);
  merges.add(merge_of(map_a));
  merges.add(merge_of(map_b));

  const auto first_b = merges.claim(b.id());  // only the map b owns
  ASSERT_TRUE(first_b.has_value());
  EXPECT_EQ(first_b->map, map_b);
  EXPECT_EQ(first_b->first_keyframe, 100 + map_b);
  EXPECT_FALSE(merges.claim(b.id()).has_value());  // its one row is claimed; a's is a's
  const auto first_a = merges.claim(a.id());
  ASSERT_TRUE(first_a.has_value());
  EXPECT_EQ(first_a->map, map_a);
  EXPECT_FALSE(merges.claim(a.id()).has_value());

  // Unclaimed: a claims it again.
  EXPECT_FALSE(merges.put_off(map_a));
  merges.unclaim(map_a);
  ASSERT_TRUE(merges.claim(a.id()).has_value());
  // Put back until a time to come: nobody claims it before then, and nobody
  // asks for its map (it waits for another map).
  merges.defer(map_a, unix_time_ns() + 3600'000'000'000);
  EXPECT_TRUE(merges.put_off(map_a));
  EXPECT_FALSE(merges.claim(a.id()).has_value());
  EXPECT_FALSE(merges.waiting_elsewhere(b.id(), unix_time_ns() + 1).has_value());
  merges.defer(map_a, 1);  // its time passed: a claims it; still nobody asks for it
  EXPECT_FALSE(merges.waiting_elsewhere(b.id(), unix_time_ns() + 1).has_value());
  ASSERT_TRUE(merges.claim(a.id()).has_value());
  merges.add(merge_of(map_a));  // a new session's work on the map: waiting, never put back
  EXPECT_FALSE(merges.put_off(map_a));
  // Waiting since before now, its owner alive: another replica may ask for its map.
  EXPECT_EQ(merges.waiting_elsewhere(b.id(), unix_time_ns() + 1), std::optional<MapId>(map_a));
  EXPECT_FALSE(merges.waiting_elsewhere(a.id(), unix_time_ns() + 1).has_value());  // its own
  EXPECT_FALSE(merges.waiting_elsewhere(b.id(), 0).has_value());                   // not waiting that long
  const auto again = merges.claim(a.id());
  ASSERT_TRUE(again.has_value());
  EXPECT_EQ(again->map, map_a);
  EXPECT_FALSE(merges.waiting_elsewhere(b.id(), unix_time_ns() + 1).has_value());  // claimed

  // A later session's work on the map replaces the row, unclaimed.
  merges.add(merge_of(map_a));
  EXPECT_TRUE(merges.claim(a.id()).has_value());
  EXPECT_FALSE(merges.put_off(map_b + 1));  // no row

  // b stops with its row claimed: the replica that takes b's maps over claims the row again.
  b.stop();
  MapOwnership ownership_a(a, uri);
  EXPECT_TRUE(contains(ownership_a.claim_free_and_dead(), map_b));
  const auto taken = merges.claim(a.id());
  ASSERT_TRUE(taken.has_value());
  EXPECT_EQ(taken->map, map_b);
  merges.remove(map_b);
  merges.remove(map_a);
  EXPECT_FALSE(merges.claim(a.id()).has_value());
}

TEST_F(SharedMergeWorkTest, AMapAskedForIsHandedOverAndTakenLikeADeadReplicasMap) {
  migrate_postgres_schema(*db_, unix_time_ns());
  const std::string uri = cluster().uri(name_);
  ReplicaRegistry a(uri, long_lease()), b(uri, long_lease());
  MapOwnership ownership_a(a, uri), ownership_b(b, uri);
  const MapId map = replica_id_range(a.id(), kReplicaMapIdShift).begin + 1;  // made by a
  own(*db_, map, a.id());
  EXPECT_TRUE(ownership_a.owns(map));
  EXPECT_FALSE(ownership_b.owns(map));
  EXPECT_TRUE(ownership_a.wanted().empty());
  EXPECT_FALSE(ownership_a.want(map));      // its own
  EXPECT_FALSE(ownership_b.want(map + 1));  // nobody owns it
  EXPECT_TRUE(ownership_b.want(map));
  const auto wanted = ownership_a.wanted();
  ASSERT_EQ(wanted.size(), 1u);
  EXPECT_EQ(wanted[0].map, map);
  EXPECT_EQ(wanted[0].by, b.id());
  EXPECT_TRUE(ownership_b.wanted().empty());

  EXPECT_FALSE(ownership_b.hand_over(map, a.id()));  // not b's to give
  EXPECT_TRUE(ownership_a.hand_over(map, b.id()));
  EXPECT_FALSE(ownership_a.owns(map));  // made by a, but b's now
  EXPECT_TRUE(ownership_a.wanted().empty());
  EXPECT_FALSE(ownership_b.owns(map));  // not before b has read it again
  EXPECT_TRUE(contains(ownership_b.claim_free_and_dead(), map));
  ownership_b.ready({map});
  EXPECT_TRUE(ownership_b.owns(map));
  EXPECT_FALSE(contains(ownership_b.claim_free_and_dead(), map));  // known as b's

  // And back to a, which made it.
  EXPECT_TRUE(ownership_a.want(map));
  EXPECT_TRUE(ownership_b.hand_over(map, a.id()));
  EXPECT_FALSE(ownership_b.owns(map));
  EXPECT_FALSE(ownership_a.owns(map));
  EXPECT_TRUE(contains(ownership_a.claim_free_and_dead(), map));
  ownership_a.ready({map});
  EXPECT_TRUE(ownership_a.owns(map));

  // A request from a replica that stopped is not handed anything.
  EXPECT_TRUE(ownership_b.want(map));
  b.stop();
  EXPECT_TRUE(ownership_a.wanted().empty());
}

}  // namespace
}  // namespace orbatlas
