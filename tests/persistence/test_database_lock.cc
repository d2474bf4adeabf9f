// One writer per atlas, on either backend: a second writer is
// refused naming the first, the lock goes with its holder, and the next holder
// learns whether the previous one stopped cleanly (the id gap after a crash).
// SQLite: a flock on "<db>.lock"; PostgreSQL: a session-level advisory lock
// and the atlas_writer row.
#include <gtest/gtest.h>
#include <unistd.h>

#include <functional>
#include <memory>
#include <string>

#include "client/effective_options.h"
#include "core/common/error.h"
#include "core/persistence/atlas_location.h"
#include "core/persistence/atlas_store.h"
#include "core/persistence/database_lock.h"
#include "tests/support/persistence_backends.h"

namespace orbatlas {
namespace {

using namespace test;  // NOLINT: the shared helpers of the persistence tests

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

class DatabaseLockTest : public AtlasBackendTest {};
ORBATLAS_PERSISTENCE_BACKENDS(DatabaseLockTest);

TEST_P(DatabaseLockTest, ASecondWriterIsRefusedNamingTheFirst) {
  auto first = std::make_unique<DatabaseLock>(location());
  EXPECT_FALSE(first->previous_holder_crashed());  // a new database
  const std::string refused = error_of([&] { DatabaseLock second(location()); });
  EXPECT_NE(refused.find("in use by another"), std::string::npos) << refused;
  EXPECT_NE(refused.find("pid " + std::to_string(::getpid())), std::string::npos) << refused;
  EXPECT_NE(refused.find("one writer per database"), std::string::npos) << refused;
  // The atlas still opens for reading and writing through the first writer's connections.
  AtlasStore store = AtlasStore::open(location(), test_vocabulary().hash());
  EXPECT_EQ(store.checkpoint_sequence(), 0);
  first.reset();  // the holder goes (PostgreSQL: its connection closes): the lock is free
  DatabaseLock again(location());
}

// Server replicas of one PostgreSQL atlas hold the lock together; a
// single writer (orbatlas run) is refused while they do, and they while it
// does. An SQLite atlas has one writer: shared is exclusive there.
TEST_P(DatabaseLockTest, ServerReplicasShareTheLockASingleWriterDoesNot) {
  auto a = std::make_unique<DatabaseLock>(location(), DatabaseLockMode::kShared);
  if (backend() == SqlDialect::kSqlite) {
    const std::string refused = error_of([&] { DatabaseLock b(location(), DatabaseLockMode::kShared); });
    EXPECT_NE(refused.find("in use by another"), std::string::npos) << refused;
    return;
  }
  {
    DatabaseLock b(location(), DatabaseLockMode::kShared);
    EXPECT_FALSE(b.previous_holder_crashed());
    const std::string refused = error_of([&] { DatabaseLock single(location()); });
    EXPECT_NE(refused.find("in use by another writer"), std::string::npos) << refused;
  }
  a.reset();
  {
    DatabaseLock single(location());  // the replicas are gone
    const std::string refused = error_of([&] { DatabaseLock replica(location(), DatabaseLockMode::kShared); });
    EXPECT_NE(refused.find("a server replica cannot start while a single writer has it"), std::string::npos) << refused;
  }
  DatabaseLock replica(location(), DatabaseLockMode::kShared);
}

TEST_P(DatabaseLockTest, TheNextHolderKnowsWhetherThePreviousOneStoppedCleanly) {
  {
    DatabaseLock clean(location());
    clean.mark_stopped();
  }
  {
    DatabaseLock after_clean(location());
    EXPECT_FALSE(after_clean.previous_holder_crashed());
  }  // dropped without mark_stopped(): what SIGKILL leaves
  DatabaseLock after_crash(location());
  EXPECT_TRUE(after_crash.previous_holder_crashed());
}

TEST(AtlasLocation, PostgresUrisAreToldApartAndCheckedBeforeConnecting) {
  EXPECT_TRUE(is_postgres_location("postgresql://u@h/db"));
  EXPECT_TRUE(is_postgres_location("postgres:///db?host=/tmp"));
  EXPECT_FALSE(is_postgres_location("atlas.db"));
  EXPECT_FALSE(is_postgres_location("/srv/postgresql/atlas.db"));
  EXPECT_EQ(location_for_messages("postgresql://me:secret@db.example:5433/atlas"),
            "postgresql://me:***@db.example:5433/atlas");
  EXPECT_EQ(location_for_messages("postgresql://me@db.example/atlas"), "postgresql://me@db.example/atlas");

  const std::string bad = error_of([] { AtlasStore::open("postgresql://me:secret@[::1/atlas", "v"); });
  EXPECT_NE(bad.find("bad PostgreSQL URI postgresql://me:***@[::1/atlas"), std::string::npos) << bad;
  EXPECT_EQ(bad.find("secret"), std::string::npos) << bad;
  const std::string unknown = error_of([] { DatabaseLock lock("postgresql:///atlas?frobnicate=1"); });
  EXPECT_NE(unknown.find("bad PostgreSQL URI"), std::string::npos) << unknown;

  // Nothing listens on that socket folder.
  const std::string unreachable =
      error_of([] { AtlasStore::open("postgresql://me:secret@/atlas?host=/nonexistent-orbatlas-test", "v"); });
  EXPECT_NE(unreachable.find("cannot connect to postgresql://me:***@/atlas"), std::string::npos) << unreachable;
  EXPECT_EQ(unreachable.find("secret"), std::string::npos) << unreachable;
}

// The options a program logs at start (orbatlas-server, orbatlas run) show a
// database URI without its password.
TEST(AtlasLocation, TheLoggedOptionsHideAUrisPassword) {
  EXPECT_EQ(without_uri_passwords("db=\"postgresql://me:secret@db.example:5433/atlas\""),
            "db=\"postgresql://me:***@db.example:5433/atlas\"");
  EXPECT_EQ(without_uri_passwords("db=postgresql://me@db.example/atlas"), "db=postgresql://me@db.example/atlas");
  EXPECT_EQ(without_uri_passwords("db=atlas.db"), "db=atlas.db");
  EXPECT_EQ(without_uri_passwords("a=postgres://u:p1@h/x b=postgres://v:p2@/y?host=/tmp"),
            "a=postgres://u:***@h/x b=postgres://v:***@/y?host=/tmp");
  CLI::App app("test");
  std::string db;
  app.add_option("--db", db);
  const char* argv[] = {"test", "--db", "postgresql://me:secret@/atlas?host=/tmp/pg"};
  app.parse(3, argv);
  const std::string text = effective_options_text(app);
  EXPECT_EQ(text.find("secret"), std::string::npos) << text;
  EXPECT_NE(text.find("postgresql://me:***@/atlas?host=/tmp/pg"), std::string::npos) << text;
}

}  // namespace
}  // namespace orbatlas
