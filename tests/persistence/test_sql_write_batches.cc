// Write transactions with many rows, on both backends: PostgreSQL
// batches a write transaction's statements (libpq's pipeline mode, pg_db.h),
// so a statement's failure may surface later than its run(). Whatever the
// backend: a failure in the middle of a long transaction throws, naming the
// database, and rolls back every row of it; the connection stays usable; a
// read after queued writes sees them; and 10,000 rows round-trip exactly.
// Then PostgreSQL's batching itself: where a failure surfaces, changes(),
// flush(), and nothing queued outside write transactions.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <string>

#include "core/common/error.h"
#include "core/persistence/pg_db.h"
#include "tests/support/persistence_backends.h"

namespace orbatlas::test {
namespace {

using PersistenceWriteBatches = AtlasBackendTest;
ORBATLAS_PERSISTENCE_BACKENDS(PersistenceWriteBatches);

void create_table(SqlConnection& db) {
  db.exec("CREATE TABLE rows_t (id bigint PRIMARY KEY, r double precision, t text, b bytea)");
}

void insert_ids(SqlConnection& db, std::int64_t first, std::int64_t last) {
  const std::unique_ptr<SqlStatement> insert = db.prepare_statement("INSERT INTO rows_t(id, r) VALUES (?1, ?2)");
  for (std::int64_t id = first; id <= last; ++id) {
    insert->bind_int64(1, id).bind_real(2, 0.5 * static_cast<double>(id));
    insert->run();
    insert->reset();
  }
}

TEST_P(PersistenceWriteBatches, AFailureInTheMiddleThrowsRollsBackAllAndLeavesTheConnectionUsable) {
  const std::unique_ptr<SqlConnection> db = raw_connection();
  create_table(*db);
  insert_ids(*db, 500, 500);  // committed: the 500th row of each transaction below collides
  // 1,000 rows: the failure surfaces at COMMIT on PostgreSQL (one batch);
  // 5,000: while later rows are queued. Either way nothing of the transaction stays.
  for (const std::int64_t rows : {1000, 5000}) {
    SCOPED_TRACE(rows);
    try {
      SqlTransaction transaction(*db);
      insert_ids(*db, 1, rows);
      transaction.commit();
      FAIL() << "a duplicate key was committed";
    } catch (const Error& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(db->description()), std::string::npos) << what;
      EXPECT_NE(what.find("INSERT INTO rows_t"), std::string::npos) << what;  // the statement
      if (backend() == SqlDialect::kPostgres) {
        EXPECT_NE(what.find("23505"), std::string::npos) << what;
      }
    }
    EXPECT_EQ(db->query_int64("SELECT count(*) FROM rows_t"), 1);
    // Usable: a transaction on the same connection commits.
    {
      SqlTransaction transaction(*db);
      insert_ids(*db, 1, 10);
      transaction.commit();
    }
    EXPECT_EQ(db->query_int64("SELECT count(*) FROM rows_t"), 11);
    db->exec("DELETE FROM rows_t WHERE id <> 500");
  }
  // A failure that is not the last statement's, then a clean transaction.
  try {
    SqlTransaction transaction(*db);
    insert_ids(*db, 400, 600);
    db->prepare_statement("UPDATE rows_t SET r = 1 WHERE id = ?1")->bind_int64(1, 10).run();
    insert_ids(*db, 1000, 1100);
    transaction.commit();
    FAIL() << "a duplicate key was committed";
  } catch (const Error&) {
  }
  EXPECT_EQ(db->query_int64("SELECT count(*) FROM rows_t"), 1);
}

TEST_P(PersistenceWriteBatches, ARollbackWithoutFailureDiscardsTheQueuedRows) {
  const std::unique_ptr<SqlConnection> db = raw_connection();
  create_table(*db);
  {
    SqlTransaction transaction(*db);
    insert_ids(*db, 1, 2500);
  }  // no commit
  EXPECT_EQ(db->query_int64("SELECT count(*) FROM rows_t"), 0);
}

TEST_P(PersistenceWriteBatches, AReadAfterQueuedWritesSeesThem) {
  const std::unique_ptr<SqlConnection> db = raw_connection();
  create_table(*db);
  SqlTransaction transaction(*db);
  insert_ids(*db, 1, 1500);
  EXPECT_EQ(db->query_int64("SELECT count(*) FROM rows_t"), 1500);
  const std::unique_ptr<SqlStatement> update = db->prepare_statement("UPDATE rows_t SET r = ?2 WHERE id = ?1");
  for (std::int64_t id = 1; id <= 1500; id += 3) {
    update->bind_int64(1, id).bind_real(2, -1.25);
    update->run();
    update->reset();
  }
  db->prepare_statement("DELETE FROM rows_t WHERE id > 1400")->run();
  const std::unique_ptr<SqlStatement> read = db->prepare_statement("SELECT id, r FROM rows_t ORDER BY id");
  std::int64_t expected = 1;
  while (read->step()) {
    ASSERT_EQ(read->int64(0), expected);
    EXPECT_EQ(read->real(1), (expected - 1) % 3 == 0 ? -1.25 : 0.5 * static_cast<double>(expected));
    ++expected;
  }
  EXPECT_EQ(expected, 1401);
  transaction.commit();
  EXPECT_EQ(db->query_int64("SELECT count(*) FROM rows_t"), 1400);
}

TEST_P(PersistenceWriteBatches, TenThousandRowsRoundTripExactly) {
  const std::unique_ptr<SqlConnection> db = raw_connection();
  create_table(*db);
  constexpr int kRows = 10000;
  const auto row_values = [](int i) {
    std::mt19937_64 rng(static_cast<std::uint64_t>(i));
    double r;
    const std::uint64_t bits = (rng() & ~(std::uint64_t{0x7ff} << 52)) | (std::uint64_t{1 + rng() % 2046} << 52);
    std::memcpy(&r, &bits, 8);  // any finite double
    std::string blob(static_cast<std::size_t>(rng() % 300), '\0');
    for (char& c : blob) c = static_cast<char>(rng());
    return std::make_tuple(r, "row " + std::to_string(i) + " 'quoted' ?", blob);
  };
  {
    SqlTransaction transaction(*db);
    const std::unique_ptr<SqlStatement> insert =
        db->prepare_statement("INSERT INTO rows_t(id, r, t, b) VALUES (?1, ?2, ?3, ?4)");
    for (int i = 0; i < kRows; ++i) {
      const auto [r, t, b] = row_values(i);
      insert->bind_int64(1, std::numeric_limits<std::int64_t>::min() + i)
          .bind_real(2, r)
          .bind_text(3, t)
          .bind_blob(4, b);
      insert->run();
      insert->reset();
    }
    transaction.commit();
  }
  const std::unique_ptr<SqlStatement> read = db->prepare_statement("SELECT id, r, t, b FROM rows_t ORDER BY id");
  int i = 0;
  while (read->step()) {
    ASSERT_LT(i, kRows);
    const auto [r, t, b] = row_values(i);
    ASSERT_EQ(read->int64(0), std::numeric_limits<std::int64_t>::min() + i);
    ASSERT_EQ(std::memcmp(&r, &static_cast<const double&>(read->real(1)), 8), 0) << i;
    ASSERT_EQ(read->text(2), t);
    ASSERT_EQ(read->blob(3), b);
    ++i;
  }
  EXPECT_EQ(i, kRows);
}

// PostgreSQL's batching itself.
using PgWriteBatches = PostgresDatabaseTest;

TEST_F(PgWriteBatches, OnlyWriteTransactionsQueue) {
  db_->exec("CREATE TABLE q (id bigint PRIMARY KEY)");
  PgStatement insert = db_->prepare("INSERT INTO q VALUES (?1)");
  insert.bind_int64(1, 1).run();  // autocommit: at once
  EXPECT_EQ(db_->queued(), 0);
  {
    PgTransaction read(*db_, PgTransaction::Mode::kRead);
    EXPECT_EQ(db_->query_int64("SELECT count(*) FROM q"), 1);
    EXPECT_EQ(db_->queued(), 0);
  }
  {
    PgTransaction write(*db_);
    insert.reset();
    insert.bind_int64(1, 2).run();
    insert.reset();
    insert.bind_int64(1, 3).run();
    EXPECT_EQ(db_->queued(), 2);
    write.commit();
    EXPECT_EQ(db_->queued(), 0);
  }
  insert.reset();
  insert.bind_int64(1, 4).run();  // autocommit again after the COMMIT
  EXPECT_EQ(db_->queued(), 0);
  EXPECT_EQ(db_->query_int64("SELECT count(*) FROM q"), 4);
}

TEST_F(PgWriteBatches, ChangesAfterAQueuedRunReadsTheQueue) {
  db_->exec("CREATE TABLE c (id bigint PRIMARY KEY, v bigint)");
  PgTransaction transaction(*db_);
  for (int i = 0; i < 7; ++i) db_->prepare("INSERT INTO c VALUES (?1, 0)").bind_int64(1, i).run();
  PgStatement update = db_->prepare("UPDATE c SET v = 1 WHERE id < ?1");
  update.bind_int64(1, 5).run();
  EXPECT_GT(db_->queued(), 0);
  EXPECT_EQ(update.changes(), 5);
  EXPECT_EQ(db_->queued(), 0);
  update.reset();
  EXPECT_THROW(update.changes(), Error);  // not run since the reset
  update.bind_int64(1, 100).run();
  update.reset();
  update.bind_int64(1, -1).run();  // the last run counts
  EXPECT_EQ(update.changes(), 0);
  transaction.commit();
}

TEST_F(PgWriteBatches, AQueuedFailureSurfacesAtTheNextReadOrFlushAndTheTransactionRollsBack) {
  db_->exec("CREATE TABLE f (id bigint PRIMARY KEY)");
  db_->prepare("INSERT INTO f VALUES (1)").run();
  {
    PgTransaction transaction(*db_);
    db_->prepare("INSERT INTO f VALUES (?1)").bind_int64(1, 2).run();
    EXPECT_NO_THROW(db_->prepare("INSERT INTO f VALUES (?1)").bind_int64(1, 1).run());  // queued
    db_->prepare("INSERT INTO f VALUES (?1)").bind_int64(1, 3).run();
    EXPECT_THROW(db_->query_int64("SELECT count(*) FROM f"), Error);  // the read reports it
    EXPECT_EQ(db_->queued(), 0);
    EXPECT_THROW(db_->exec("COMMIT"), Error);  // aborted: never a silent ROLLBACK-as-COMMIT
  }                                            // the destructor's ROLLBACK
  EXPECT_EQ(db_->query_int64("SELECT count(*) FROM f"), 1);
  {
    PgTransaction transaction(*db_);
    db_->prepare("INSERT INTO f VALUES (?1)").bind_int64(1, 1).run();
    try {
      db_->flush();
      FAIL() << "flush() did not report the duplicate key";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("INSERT INTO f VALUES ($1)"), std::string::npos) << e.what();
    }
  }
  {
    PgTransaction transaction(*db_);
    db_->prepare("INSERT INTO f VALUES (?1)").bind_int64(1, 5).run();
    transaction.commit();
  }
  EXPECT_EQ(db_->query_int64("SELECT count(*) FROM f"), 2);
}

TEST_F(PgWriteBatches, ALongTransactionReportsAFailureBeforeItsCommit) {
  db_->exec("CREATE TABLE l (id bigint PRIMARY KEY)");
  db_->prepare("INSERT INTO l VALUES (500)").run();
  PgTransaction transaction(*db_);
  PgStatement insert = db_->prepare("INSERT INTO l VALUES (?1)");
  int queued = 0;
  try {
    for (int id = 1; id <= 10 * PgDb::kPipelineBatch; ++id) {
      insert.bind_int64(1, id).run();
      insert.reset();
      ++queued;
    }
    FAIL() << "no failure before the commit";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("23505"), std::string::npos) << e.what();
  }
  EXPECT_GE(queued, 500);  // from the batch before the last, so at most two batches later
  EXPECT_LE(queued, 2 * PgDb::kPipelineBatch);
  EXPECT_EQ(db_->queued(), 0);
}

TEST_F(PgWriteBatches, BlobsLargerThanLibpqsBuffersInOneBatch) {
  db_->exec("CREATE TABLE big (id bigint PRIMARY KEY, b bytea)");
  const std::string blob(300 * 1024, 'x');  // ~ three keyframes' features
  {
    PgTransaction transaction(*db_);
    PgStatement insert = db_->prepare("INSERT INTO big VALUES (?1, ?2)");
    for (int id = 0; id < 200; ++id) {
      insert.bind_int64(1, id).bind_blob(2, blob);
      insert.run();
      insert.reset();
    }
    transaction.commit();
  }
  EXPECT_EQ(db_->query_int64("SELECT sum(length(b)) FROM big"), 200 * static_cast<std::int64_t>(blob.size()));
}

}  // namespace
}  // namespace orbatlas::test
