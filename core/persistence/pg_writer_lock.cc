#include "core/persistence/pg_writer_lock.h"

#include <unistd.h>

#include <climits>

#include "core/common/error.h"
#include "core/persistence/pg_db.h"
#include "core/persistence/pg_schema.h"
#include "core/persistence/process_holder.h"
#include "core/persistence/wall_clock.h"

namespace orbatlas {
namespace {

// pg_try_advisory_lock's key for the atlas's writer (advisory locks are per
// database, and a database holds one atlas): "orbatlaw".
constexpr std::int64_t kWriterLockKey = 0x6f726261746c6177;
// How long a new writer waits for the previous writer's lock to go.
constexpr int kWaitMs = 3000;

}  // namespace

PgWriterLock::PgWriterLock(const std::string& conninfo, bool shared)
    : db_(std::make_unique<PgDb>(conninfo)), shared_(shared) {
  migrate_postgres_schema(*db_, unix_time_ns());
  // The lock of a writer that just stopped or died goes when the server has
  // ended its connection, which libpq does not wait for: the server waits for
  // the lock (kWaitMs at most) rather than refusing a restart that came first.
  bool taken = false;
  db_->exec("SET lock_timeout = " + std::to_string(kWaitMs));
  try {
    PgStatement take = db_->prepare(shared_ ? "SELECT pg_advisory_lock_shared(?1)" : "SELECT pg_advisory_lock(?1)");
    take.bind_int64(1, kWriterLockKey);
    take.step();
    taken = true;
  } catch (const Error& e) {
    if (std::string(e.what()).find("SQLSTATE 55P03") == std::string::npos) throw;  // not the timeout
  }
  db_->exec("SET lock_timeout = 0");
  if (!taken) {
    // Server replicas holding it together, or the single writer.
    std::string who;
    PgStatement replicas =
        db_->prepare("SELECT holder FROM replicas WHERE state = 'running' AND lease_until >= now() ORDER BY id");
    while (replicas.step()) who += (who.empty() ? "orbatlas-server replicas: " : ", ") + replicas.text(0);
    if (who.empty()) {
      PgStatement holder = db_->prepare("SELECT holder FROM atlas_writer WHERE id = 1");
      who = holder.step() ? holder.text(0) : std::string("unknown holder");
    }
    throw Error(
        "the atlas " + db_->description() + " is in use by another writer (" + who +
        (shared_ ? "); a server replica cannot start while a single writer has it" : "); one writer per database"));
  }
  if (shared_) return;
  PgStatement state = db_->prepare("SELECT state FROM atlas_writer WHERE id = 1");
  previous_crashed_ = state.step() && state.text(0) == "running";
  db_->prepare(
         "INSERT INTO atlas_writer(id, state, holder, changed_ns) VALUES (1, 'running', ?1, ?2) "
         "ON CONFLICT (id) DO UPDATE SET state = excluded.state, holder = excluded.holder, "
         "changed_ns = excluded.changed_ns")
      .bind_text(1, process_holder())
      .bind_int64(2, unix_time_ns())
      .run();
}

PgWriterLock::~PgWriterLock() {
  // Released at once on a clean drop (a crash leaves it to the server).
  try {
    db_->prepare(shared_ ? "SELECT pg_advisory_unlock_shared(?1)" : "SELECT pg_advisory_unlock(?1)")
        .bind_int64(1, kWriterLockKey)
        .step();
  } catch (const std::exception&) {  // the connection is gone: so is the lock
  }
}

void PgWriterLock::mark_stopped() {
  if (shared_) return;
  db_->prepare("UPDATE atlas_writer SET state = 'stopped', changed_ns = ?1 WHERE id = 1")
      .bind_int64(1, unix_time_ns())
      .run();
}

}  // namespace orbatlas
