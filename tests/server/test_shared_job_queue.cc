// The upload queue every replica of a PostgreSQL atlas takes from
// (core/server/shared_job_queue.h), on a throwaway cluster: claims in order and
// never twice, the jobs of a replica that stopped wait again, an upload it was
// receiving fails; the stored session request round-trips.
#include <gtest/gtest.h>

#include <string>

#include "core/common/error.h"
#include "core/persistence/job_rows.h"
#include "core/persistence/pg_schema.h"
#include "core/persistence/wall_clock.h"
#include "core/server/replica_registry.h"
#include "core/server/shared_job_queue.h"
#include "core/server/shared_merges.h"
#include "tests/support/throwaway_postgres.h"

namespace orbatlas {
namespace {

using SharedJobQueueTest = test::PostgresDatabaseTest;

StoredJob job_row(std::uint64_t id, const std::string& state) {
  StoredJob j;
  j.id = id;
  j.name = "upload " + std::to_string(id);
  j.state = state;
  j.created_ns = 1;
  return j;
}

std::string state_of(PgDb& db, std::uint64_t id) {
  for (const StoredJob& j : read_jobs(db))
    if (j.id == id) return j.state;
  return "missing";
}

TEST_F(SharedJobQueueTest, JobsAreClaimedInOrderOnceAndADeadReplicasWaitAgain) {
  migrate_postgres_schema(*db_, unix_time_ns());
  const std::string uri = cluster().uri(name_);
  ReplicaOptions lease;
  lease.lease_s = 10.0;
  ReplicaRegistry a(uri, lease), b(uri, lease);
  SharedJobQueue qa(a, uri), qb(b, uri);
  const std::uint64_t base = replica_id_range(a.id(), kReplicaMapIdShift).begin;
  SessionRequest request;
  request.name = "MH_01";
  request.settings.config = "euroc/stereo";
  for (std::uint64_t k = 1; k <= 3; ++k) {
    write_job(*db_, job_row(base + k, "queued"));
    qa.add(base + k, "/shared/upload-" + std::to_string(k), request);
  }
  EXPECT_EQ(qb.waiting(), 3u);
  const auto first = qa.claim();
  ASSERT_TRUE(first.has_value());
  EXPECT_EQ(first->id, base + 1);  // the oldest
  EXPECT_EQ(first->folder, "/shared/upload-1");
  EXPECT_EQ(first->request.name, "MH_01");
  EXPECT_EQ(first->request.settings.config, "euroc/stereo");
  write_job(*db_, job_row(base + 1, "running"));
  const auto second = qb.claim();  // another replica: the next one
  ASSERT_TRUE(second.has_value());
  EXPECT_EQ(second->id, base + 2);
  EXPECT_EQ(qa.waiting(), 1u);
  // An upload a was still receiving (not queued yet).
  write_job(*db_, job_row(base + 4, "extracting"));

  a.stop();  // a is gone (as if its lease had passed): its running job waits again
  EXPECT_EQ(qb.requeue_dead(), 1u);
  EXPECT_EQ(state_of(*db_, base + 1), "queued");
  EXPECT_EQ(state_of(*db_, base + 4), "failed");
  EXPECT_EQ(qb.waiting(), 2u);
  const auto again = qb.claim();
  ASSERT_TRUE(again.has_value());
  EXPECT_EQ(again->id, base + 1);
  qb.remove(base + 1);
  qb.remove(base + 2);
  const auto last = qb.claim();
  ASSERT_TRUE(last.has_value());
  EXPECT_EQ(last->id, base + 3);
  EXPECT_FALSE(qb.claim().has_value());  // nothing left
  EXPECT_EQ(qb.waiting(), 0u);
}

TEST(SharedJobQueue, TheSessionRequestRoundTrips) {
  SessionRequest r;
  r.name = "a \"quoted\" name";
  r.sensor = "stereo_inertial";
  r.mode = "map";
  r.settings.config = "euroc/stereo_inertial";
  r.settings.settings_yaml = "%YAML:1.0\nCamera.fx: 458.654\n";
  r.max_lag_s = 0.1;
  const SessionRequest back = session_request_from_json(session_request_json(r));
  EXPECT_EQ(back.name, r.name);
  EXPECT_EQ(back.sensor, r.sensor);
  EXPECT_EQ(back.mode, r.mode);
  EXPECT_EQ(back.settings.config, r.settings.config);
  EXPECT_EQ(back.settings.settings_yaml, r.settings.settings_yaml);
  EXPECT_EQ(back.max_lag_s, r.max_lag_s);
  EXPECT_FALSE(session_request_from_json(session_request_json(SessionRequest{})).max_lag_s.has_value());
  EXPECT_THROW(session_request_from_json("{\"name\": 3}"), DataError);
  EXPECT_THROW(session_request_from_json("not json"), DataError);
}

// The merge work a finished session leaves (shared_merges.h): stored, read back
// for the maps asked, replaced, removed.
TEST_F(SharedJobQueueTest, MergeWorkIsStoredPerMapAndReadBackExactly) {
  migrate_postgres_schema(*db_, unix_time_ns());
  SharedMerges merges(cluster().uri(name_));
  StoredMerge visual{7, {"euroc/stereo", ""}, 123, std::nullopt, false};
  StoredMerge inertial{9, {"", "%YAML:1.0\n"}, 456, GlobalBundleAdjustmentOptions::Inertial{}, true};
  inertial.inertial->T_b_i = Pose3(Eigen::Quaterniond(0.5, 0.5, -0.5, 0.5), Eigen::Vector3d(0.1, -0.2, 0.3));
  inertial.inertial->max_chain_keyframes = 77;
  merges.add(visual);
  merges.add(inertial);
  const auto read = merges.of({9, 8, 7});
  ASSERT_EQ(read.size(), 2u);
  EXPECT_EQ(read[0].map, 9u);
  EXPECT_EQ(read[0].settings.settings_yaml, "%YAML:1.0\n");
  EXPECT_EQ(read[0].first_keyframe, 456u);
  EXPECT_TRUE(read[0].single_camera);
  ASSERT_TRUE(read[0].inertial.has_value());
  EXPECT_EQ(read[0].inertial->T_b_i.t, inertial.inertial->T_b_i.t);
  EXPECT_EQ(read[0].inertial->T_b_i.q.coeffs(), inertial.inertial->T_b_i.q.coeffs());
  EXPECT_EQ(read[0].inertial->max_chain_keyframes, 77u);
  EXPECT_EQ(read[0].inertial->huber, inertial.inertial->huber);
  EXPECT_EQ(read[1].map, 7u);
  EXPECT_EQ(read[1].settings.config, "euroc/stereo");
  EXPECT_FALSE(read[1].inertial.has_value());
  visual.first_keyframe = 124;  // a later session's work on the same map replaces it
  merges.add(visual);
  EXPECT_EQ(merges.of({7})[0].first_keyframe, 124u);
  merges.remove(7);
  EXPECT_TRUE(merges.of({7}).empty());
  EXPECT_THROW(stored_merge_from_json(1, "{\"config\": 1}"), DataError);
}

}  // namespace
}  // namespace orbatlas
