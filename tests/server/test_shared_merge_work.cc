// Merge work shared between the replicas of a PostgreSQL atlas
// (core/server/shared_merges.h, core/server/map_ownership.h), on a throwaway
// cluster: a map's merge row is claimed by the replica that owns the map, once;
// put back as it was, or until a retry time (then nobody asks for its map);
// asked for by another replica once it waited;
// a map asked for is handed over and taken like a dead replica's; the rows of
// a replica that stopped go with its maps; a map merged away loses its owner
// with its rows only, never claimed back by its maker; the live sessions of a replica
// gone become rows of the maps their keyframes are in.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <unordered_set>

#include "core/persistence/pg_schema.h"
#include "core/persistence/wall_clock.h"
#include "core/server/map_ownership.h"
#include "core/server/replica_registry.h"
#include "core/server/shared_merges.h"
#include "tests/support/throwaway_postgres.h"

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

bool owned_by(const MapOwnership& ownership, MapId map, std::uint64_t replica) {
  for (const MapOwnership::Owned& o : ownership.owners())
    if (o.map == map) return o.replica == replica;
  return false;
}

bool has_owner(const MapOwnership& ownership, MapId map) {
  const auto owners = ownership.owners();
  return std::any_of(owners.begin(), owners.end(), [&](const MapOwnership::Owned& o) { return o.map == map; });
}

// A map a made, handed over to b and merged away there: its owner row goes only
// with the checkpoint that deletes its rows (not with one whose snapshot still
// had it: that one writes it as it was), and a's stale copy never claims it back.
TEST_F(SharedMergeWorkTest, AMapMergedAwayKeepsItsOwnerUntilItsRowsGoAndItsMakerNeverClaimsItBack) {
  migrate_postgres_schema(*db_, unix_time_ns());
  const std::string uri = cluster().uri(name_);
  ReplicaRegistry a(uri, long_lease()), b(uri, long_lease());
  MapOwnership ownership_a(a, uri), ownership_b(b, uri);
  const MapId map = replica_id_range(a.id(), kReplicaMapIdShift).begin + 1;  // made by a
  db_->prepare("INSERT INTO maps(id, saved_ns) VALUES (?1, 0)").bind_int64(1, static_cast<std::int64_t>(map)).run();
  EXPECT_EQ(ownership_a.writable(*db_, {map}, {}), std::unordered_set<MapId>{map});  // a's first checkpoint claims it
  EXPECT_TRUE(owned_by(ownership_a, map, a.id()));
  ASSERT_TRUE(ownership_b.want(map));
  ASSERT_TRUE(ownership_a.hand_over(map, b.id()));
  ASSERT_TRUE(contains(ownership_b.claim_free_and_dead(), map));
  ownership_b.ready({map});

  // b merges it away after a checkpoint's snapshot: that checkpoint writes it as it was, and it stays b's.
  EXPECT_EQ(ownership_b.writable(*db_, {map}, {}), std::unordered_set<MapId>{map});
  EXPECT_TRUE(owned_by(ownership_b, map, b.id()));
  EXPECT_FALSE(contains(ownership_a.claim_free_and_dead(), map));  // not a stored map without an owner
  // a's checkpoints (a still reads its copy) neither write it nor claim it.
  EXPECT_TRUE(ownership_a.writable(*db_, {map}, {}).empty());
  EXPECT_TRUE(owned_by(ownership_b, map, b.id()));

  // b's next checkpoint deletes its rows, and its owner row with them.
  EXPECT_EQ(ownership_b.writable(*db_, {map}, {map}), std::unordered_set<MapId>{map});
  db_->prepare("DELETE FROM maps WHERE id = ?1").bind_int64(1, static_cast<std::int64_t>(map)).run();
  EXPECT_FALSE(has_owner(ownership_a, map));
  // a's stale copy does not bring its ownership back (its rows would collide with b's merged map's).
  EXPECT_TRUE(ownership_a.writable(*db_, {map}, {}).empty());
  EXPECT_FALSE(has_owner(ownership_a, map));
  EXPECT_FALSE(contains(ownership_a.claim_free_and_dead(), map));
  EXPECT_FALSE(ownership_a.owns(map));
}

// A stored map, and a session with one keyframe in it (the columns as a checkpoint writes them, values unused).
void map_with_session_keyframe(PgDb& db, MapId map, SessionId session, KeyframeId keyframe) {
  db.prepare("INSERT INTO maps(id, saved_ns) VALUES (?1, 0) ON CONFLICT DO NOTHING")
      .bind_int64(1, static_cast<std::int64_t>(map))
      .run();
  db.prepare(
        "INSERT INTO sessions(id, name, sensor, created_ns) VALUES (?1, 'test', 'stereo', 0) ON CONFLICT DO NOTHING")
      .bind_int64(1, static_cast<std::int64_t>(session))
      .run();
  db.prepare(
        "INSERT INTO keyframes(id, map_id, session_id, timestamp_ns, qw, qx, qy, qz, tx, ty, tz, c_qw, c_qx, c_qy, "
        "c_qz, c_tx, c_ty, c_tz, slot_count, features) VALUES (?1, ?2, ?3, 0, 1, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, "
        "0, 0, ''::bytea)")
      .bind_int64(1, static_cast<std::int64_t>(keyframe))
      .bind_int64(2, static_cast<std::int64_t>(map))
      .bind_int64(3, static_cast<std::int64_t>(session))
      .run();
}

TEST_F(SharedMergeWorkTest, TheLiveSessionsOfAReplicaGoneBecomeRowsOfTheirMaps) {
  migrate_postgres_schema(*db_, unix_time_ns());
  const std::string uri = cluster().uri(name_);
  ReplicaRegistry a(uri, long_lease()), b(uri, long_lease());
  const MapId map_1 = replica_id_range(a.id(), kReplicaMapIdShift).begin + 1, map_2 = map_1 + 1, map_3 = map_1 + 2;
  const MapId map_b = replica_id_range(b.id(), kReplicaMapIdShift).begin + 1;
  const SessionId live = replica_id_range(a.id(), kReplicaMapIdShift).begin + 7;  // maps 1 and 2 (lost, then again)
  const SessionId finished = live + 1, on_b = replica_id_range(b.id(), kReplicaMapIdShift).begin + 7;
  map_with_session_keyframe(*db_, map_1, live, 1);
  map_with_session_keyframe(*db_, map_2, live, 2);
  map_with_session_keyframe(*db_, map_2, live, 3);
  map_with_session_keyframe(*db_, map_3, finished, 4);
  map_with_session_keyframe(*db_, map_b, on_b, 5);
  SharedMerges merges(uri);
  merges.begin_session(live, a.id(), merge_of(0));
  merges.begin_session(finished, a.id(), merge_of(1));
  merges.begin_session(on_b, b.id(), merge_of(2));
  merges.end_session(finished);                                   // its maps' rows were its replica's to add
  EXPECT_TRUE(merges.adopt_sessions_of_gone_replicas().empty());  // a and b alive: theirs
  EXPECT_TRUE(merges.of({map_1, map_2, map_3, map_b}).empty());

  a.stop();  // its live session never finished
  std::vector<MapId> adopted = merges.adopt_sessions_of_gone_replicas();
  std::sort(adopted.begin(), adopted.end());
  EXPECT_EQ(adopted, (std::vector<MapId>{map_1, map_2}));
  const auto rows = merges.of({map_1, map_2, map_3, map_b});
  ASSERT_EQ(rows.size(), 2u);
  for (const StoredMerge& row : rows) {
    EXPECT_EQ(row.first_keyframe, 100u) << row.map;  // the session's request
    EXPECT_EQ(row.settings.config, "euroc/stereo");
  }
  EXPECT_TRUE(merges.adopt_sessions_of_gone_replicas().empty());  // once

  // A map that has a row keeps it; b's session is b's until b is gone too.
  merges.add(merge_of(map_b));
  b.stop();
  EXPECT_TRUE(merges.adopt_sessions_of_gone_replicas().empty());
  const auto kept = merges.of({map_b});
  ASSERT_EQ(kept.size(), 1u);
  EXPECT_EQ(kept[0].first_keyframe, 100 + map_b);
  PgStatement left = db_->prepare("SELECT count(*) FROM shared_session_work");
  ASSERT_TRUE(left.step());
  EXPECT_EQ(left.int64(0), 0);
}

}  // namespace
}  // namespace orbatlas
