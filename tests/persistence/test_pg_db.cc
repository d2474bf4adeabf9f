// The PostgreSQL connection wrapper against a throwaway cluster:
// values round-trip exactly in binary, the typed readers are as strict as
// SQLite's, transactions commit and roll back, and failures are clear errors.
// Skipped, with the reason, where PostgreSQL's binaries are missing.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "core/common/error.h"
#include "core/persistence/pg_db.h"
#include "tests/support/throwaway_postgres.h"

namespace orbatlas {
namespace {

TEST(SqliteParamsToPostgres, NumbersBareMarksAndQuotes) {
  EXPECT_EQ(sqlite_params_to_postgres("SELECT ?1, ?2, ?10"), "SELECT $1, $2, $10");
  EXPECT_EQ(sqlite_params_to_postgres("VALUES (?, ?, ?)"), "VALUES ($1, $2, $3)");
  EXPECT_EQ(sqlite_params_to_postgres("VALUES (?3, ?)"), "VALUES ($3, $4)");  // SQLite: one above the largest
  EXPECT_EQ(sqlite_params_to_postgres("SELECT '?', \"a?\" WHERE x = ?"), "SELECT '?', \"a?\" WHERE x = $1");
  EXPECT_EQ(sqlite_params_to_postgres("SELECT 'it''s ?' || ?"), "SELECT 'it''s ?' || $1");
  EXPECT_EQ(sqlite_params_to_postgres("SELECT 1"), "SELECT 1");
  int count = -1;  // the statement's parameters: the largest number
  sqlite_params_to_postgres("VALUES (?3, ?)", &count);
  EXPECT_EQ(count, 4);
  sqlite_params_to_postgres("VALUES (?2, ?7, ?1)", &count);
  EXPECT_EQ(count, 7);
  sqlite_params_to_postgres("SELECT '?5'", &count);
  EXPECT_EQ(count, 0);
}

using PgDbTest = test::PostgresDatabaseTest;

TEST_F(PgDbTest, ValuesRoundTripExactly) {
  db_->exec("CREATE TABLE v (id bigint PRIMARY KEY, r double precision, t text, b bytea, i int, s smallint)");
  const std::string blob("\0\x01\xff\x7f binary \0", 13);
  const double reals[] = {0.1, -0.0, 1e300, -1e-300, std::numeric_limits<double>::denorm_min(), M_PI};
  std::int64_t id = std::numeric_limits<std::int64_t>::min();
  for (const double r : reals) {
    db_->prepare("INSERT INTO v(id, r, t, b, i, s) VALUES (?1, ?2, ?3, ?4, 7, -3)")
        .bind_int64(1, id)
        .bind_real(2, r)
        .bind_text(3, "grüße, 'quoted' ?")
        .bind_blob(4, blob)
        .run();
    ++id;
  }
  db_->prepare("INSERT INTO v(id, r, t, b) VALUES (?, ?, ?, ?)")
      .bind_int64(1, std::numeric_limits<std::int64_t>::max())
      .bind_null(2)
      .bind_text(3, "")
      .bind_blob(4, "")
      .run();

  PgStatement rows = db_->prepare("SELECT id, r, t, b, i, s FROM v ORDER BY id");
  for (const double r : reals) {
    ASSERT_TRUE(rows.step());
    EXPECT_EQ(std::signbit(rows.real(1)), std::signbit(r));
    EXPECT_EQ(rows.real(1), r);
    EXPECT_EQ(rows.text(2), "grüße, 'quoted' ?");
    EXPECT_EQ(rows.blob(3), blob);
    EXPECT_EQ(rows.int64(4), 7);
    EXPECT_EQ(rows.int64(5), -3);
    EXPECT_EQ(rows.real(4), 7.0);  // integers read as reals, as in SQLite
  }
  ASSERT_TRUE(rows.step());
  EXPECT_EQ(rows.int64(0), std::numeric_limits<std::int64_t>::max());
  EXPECT_TRUE(rows.is_null(1));
  EXPECT_THROW(rows.real(1), DataError);  // NULL for a typed reader
  EXPECT_EQ(rows.text(2), "");
  EXPECT_FALSE(rows.is_null(3));  // an empty blob stays a blob
  EXPECT_EQ(rows.blob(3), "");
  EXPECT_THROW(rows.int64(2), DataError);  // text where an integer belongs
  EXPECT_THROW(rows.blob(2), DataError);
  EXPECT_THROW(rows.text(0), DataError);
  EXPECT_FALSE(rows.step());

  EXPECT_EQ(db_->query_int64("SELECT count(*) FROM v"), 7);
  PgStatement update = db_->prepare("UPDATE v SET i = ?1 WHERE i = 7");
  update.bind_int64(1, 8).run();
  EXPECT_EQ(update.changes(), 6);
  update.reset();
  update.bind_int64(1, 9).run();  // reset: runs again with new bindings
  EXPECT_EQ(update.changes(), 0);

  // Parameters left unbound are NULL, the last ones too (as in SQLite), also
  // after a reset; an index past the statement's parameters is refused.
  PgStatement partial = db_->prepare("SELECT ?1::bigint IS NULL, ?2::bigint IS NULL");
  partial.bind_int64(1, 5);
  ASSERT_TRUE(partial.step());
  EXPECT_EQ(partial.int64(0), 0);
  EXPECT_EQ(partial.int64(1), 1);
  partial.reset();
  ASSERT_TRUE(partial.step());
  EXPECT_EQ(partial.int64(0), 1);
  partial.reset();
  EXPECT_THROW(partial.bind_int64(3, 1), Error);
  EXPECT_THROW(partial.bind_int64(0, 1), Error);
}

TEST_F(PgDbTest, TransactionsCommitAndRollBack) {
  db_->exec("CREATE TABLE k (id bigint PRIMARY KEY)");
  {
    PgTransaction t(*db_);
    db_->prepare("INSERT INTO k VALUES (?1)").bind_int64(1, 1).run();
  }  // no commit: rolled back
  EXPECT_EQ(db_->query_int64("SELECT count(*) FROM k"), 0);
  {
    PgTransaction t(*db_);
    db_->prepare("INSERT INTO k VALUES (?1)").bind_int64(1, 2).run();
    t.commit();
  }
  EXPECT_EQ(db_->query_int64("SELECT count(*) FROM k"), 1);

  // A read transaction sees one snapshot: another connection's commit stays
  // invisible until it ends.
  PgDb other(cluster().conninfo(name_));
  {
    PgTransaction read(*db_, PgTransaction::Mode::kRead);
    EXPECT_EQ(db_->query_int64("SELECT count(*) FROM k"), 1);
    other.prepare("INSERT INTO k VALUES (?1)").bind_int64(1, 3).run();
    EXPECT_EQ(db_->query_int64("SELECT count(*) FROM k"), 1);
    EXPECT_THROW(db_->exec("INSERT INTO k VALUES (4)"), Error);  // read only
  }
  EXPECT_EQ(db_->query_int64("SELECT count(*) FROM k"), 2);
}

TEST_F(PgDbTest, FailuresAreClearErrors) {
  db_->exec("CREATE TABLE u (id bigint PRIMARY KEY)");
  db_->prepare("INSERT INTO u VALUES (?1)").bind_int64(1, 1).run();
  try {
    db_->prepare("INSERT INTO u VALUES (?1)").bind_int64(1, 1).run();
    FAIL() << "a duplicate key was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("23505"), std::string::npos) << e.what();  // unique_violation
    EXPECT_NE(std::string(e.what()).find("postgresql"), std::string::npos) << e.what();
  }
  EXPECT_THROW(db_->exec("SELEC 1"), Error);
  EXPECT_THROW(db_->query_int64("SELECT id FROM u WHERE id = 99"), Error);  // no row
  PgStatement s = db_->prepare("SELECT id FROM u");
  EXPECT_THROW(s.int64(0), Error);  // before step()
  ASSERT_TRUE(s.step());
  EXPECT_THROW(s.int64(3), Error);  // no such column
  EXPECT_THROW(PgDb("host=/nonexistent/socket/dir dbname=x user=orbatlas connect_timeout=2"), Error);
  // The connection still works after each failure.
  EXPECT_EQ(db_->query_int64("SELECT count(*) FROM u"), 1);
}

}  // namespace
}  // namespace orbatlas
