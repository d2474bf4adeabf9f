// The replicas of one atlas database (core/server/replica_registry.h):
// registered, renewed, stopped, and seen dead by the others when killed, on a
// throwaway PostgreSQL cluster; an SQLite atlas's one server.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <functional>
#include <thread>

#include "core/common/error.h"
#include "core/persistence/pg_schema.h"
#include "core/persistence/wall_clock.h"
#include "core/server/replica_registry.h"
#include "tests/support/throwaway_postgres.h"

namespace orbatlas {
namespace {

using ReplicaRegistryTest = test::PostgresDatabaseTest;

ReplicaOptions lease(double seconds, const std::string& url = "") {
  ReplicaOptions o;
  o.lease_s = seconds;
  o.url = url;
  return o;
}

// Waits up to `timeout_s` for `done` (checked every 20 ms).
bool eventually(const std::function<bool()>& done, double timeout_s) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (std::chrono::steady_clock::now() < end) {
    if (done()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return done();
}

const ReplicaInfo* find(const std::vector<ReplicaInfo>& replicas, std::uint64_t id) {
  for (const auto& r : replicas)
    if (r.id == id) return &r;
  return nullptr;
}

TEST_F(ReplicaRegistryTest, TwoReplicasSeeEachOtherAndAStoppedOneIsNotAlive) {
  migrate_postgres_schema(*db_, unix_time_ns());
  const std::string uri = cluster().uri(name_);
  ReplicaRegistry a(uri, lease(10.0, "http://a:1"));
  ReplicaRegistry b(uri, lease(10.0));
  EXPECT_TRUE(a.shared());
  EXPECT_NE(a.id(), b.id());
  b.set_url("http://b:2");
  for (const ReplicaRegistry* r : {&a, &b}) {
    const auto all = r->replicas();
    ASSERT_EQ(all.size(), 2u);
    EXPECT_LT(all[0].id, all[1].id);  // by id
    for (const auto& info : all) {
      EXPECT_TRUE(info.alive);
      EXPECT_EQ(info.state, "running");
      EXPECT_EQ(info.self, info.id == r->id());
      ASSERT_TRUE(info.lease_left_s.has_value());
      EXPECT_GT(*info.lease_left_s, 8.0);
      EXPECT_LE(*info.lease_left_s, 10.0);
      EXPECT_NE(info.holder.find("pid " + std::to_string(::getpid())), std::string::npos) << info.holder;
      EXPECT_GT(info.started_ns, 0);
    }
    EXPECT_EQ(find(all, a.id())->url, "http://a:1");
    EXPECT_EQ(find(all, b.id())->url, "http://b:2");
  }
  b.stop();
  b.stop();  // idempotent
  const auto after = a.replicas();
  ASSERT_EQ(after.size(), 2u);
  EXPECT_EQ(find(after, b.id())->state, "stopped");
  EXPECT_FALSE(find(after, b.id())->alive);
  EXPECT_TRUE(find(after, a.id())->alive);
}

TEST_F(ReplicaRegistryTest, ALeaseIsRenewedWhileTheReplicaRuns) {
  migrate_postgres_schema(*db_, unix_time_ns());
  ReplicaRegistry a(cluster().uri(name_), lease(0.6));
  // Renewed every 0.2 s: alive well past its first lease.
  ASSERT_TRUE(eventually([&] { return a.renewals() >= 6; }, 10.0)) << a.renewals();
  const auto all = a.replicas();
  ASSERT_EQ(all.size(), 1u);
  EXPECT_TRUE(all[0].alive);
  EXPECT_GT(*all[0].lease_left_s, 0.0);
  EXPECT_EQ(a.failed_renewals(), 0u);
  EXPECT_FALSE(a.lease_lost());
}

TEST_F(ReplicaRegistryTest, AKilledReplicaIsDeadOnceItsLeasePasses) {
  migrate_postgres_schema(*db_, unix_time_ns());
  const std::string uri = cluster().uri(name_);
  ReplicaRegistry a(uri, lease(10.0));
  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {  // another replica, killed below without stopping
    ::close(fds[0]);
    try {
      ReplicaRegistry b(uri, lease(0.5));
      const std::uint64_t id = b.id();
      if (::write(fds[1], &id, sizeof id) != sizeof id) ::_exit(2);
      ::pause();
    } catch (...) {
    }
    ::_exit(1);
  }
  ::close(fds[1]);
  std::uint64_t b_id = 0;
  ASSERT_EQ(::read(fds[0], &b_id, sizeof b_id), static_cast<ssize_t>(sizeof b_id));
  ::close(fds[0]);
  const ReplicaInfo* b = find(a.replicas(), b_id);
  ASSERT_NE(b, nullptr);
  ASSERT_EQ(::kill(child, SIGKILL), 0);
  ASSERT_EQ(::waitpid(child, nullptr, 0), child);
  std::vector<ReplicaInfo> all;
  ASSERT_TRUE(eventually(
      [&] {
        all = a.replicas();
        return !find(all, b_id)->alive;
      },
      5.0));
  EXPECT_EQ(find(all, b_id)->state, "running");  // it never said it stopped
  EXPECT_LT(*find(all, b_id)->lease_left_s, 0.0);
  EXPECT_TRUE(find(all, a.id())->alive);
}

TEST_F(ReplicaRegistryTest, ALeaseThatPassedIsNotRenewed) {
  migrate_postgres_schema(*db_, unix_time_ns());
  ReplicaRegistry a(cluster().uri(name_), lease(0.6));
  // As if this process had been stopped for longer than its lease.
  db_->prepare("UPDATE replicas SET lease_until = now() - interval '1 second' WHERE id = ?1")
      .bind_int64(1, static_cast<std::int64_t>(a.id()))
      .run();
  ASSERT_TRUE(eventually([&] { return a.lease_lost(); }, 5.0));
  const auto all = a.replicas();
  ASSERT_EQ(all.size(), 1u);
  EXPECT_FALSE(all[0].alive);
  EXPECT_LT(*all[0].lease_left_s, 0.0);
}

TEST_F(ReplicaRegistryTest, AnUnreachableDatabaseIsAnErrorAtStart) {
  const std::string uri = cluster().uri("no_such_database");
  EXPECT_THROW(ReplicaRegistry(uri, lease(1.0)), Error);
}

TEST(ReplicaRegistry, AnSqliteAtlasHasOneReplicaWithoutALease) {
  ReplicaRegistry a("/tmp/not_opened_by_the_registry.db", lease(1.0, "http://x:3"));
  EXPECT_FALSE(a.shared());
  EXPECT_EQ(a.id(), 1u);
  const auto all = a.replicas();
  ASSERT_EQ(all.size(), 1u);
  EXPECT_TRUE(all[0].alive);
  EXPECT_TRUE(all[0].self);
  EXPECT_EQ(all[0].url, "http://x:3");
  EXPECT_FALSE(all[0].lease_left_s.has_value());
  a.stop();
  EXPECT_EQ(a.replicas()[0].state, "stopped");
}

TEST(ReplicaRegistry, OptionsAreChecked) {
  EXPECT_THROW(lease(0.1).check(), Error);
  EXPECT_THROW(lease(-1.0).check(), Error);
  EXPECT_THROW(lease(std::nan("")).check(), Error);
  EXPECT_THROW(lease(4000.0).check(), Error);
  EXPECT_NO_THROW(lease(10.0).check());
}

}  // namespace
}  // namespace orbatlas
