#pragma once
// The single-writer guarantee of an atlas in PostgreSQL: what the
// lock file is for SQLite (database_lock.h). The writer holds a session-level
// advisory lock (pg_advisory_lock) on a connection of its own for its whole
// life; PostgreSQL releases it when that connection ends, however the process
// ended (exit, SIGKILL, a crash: the server sees the socket close). That
// happens shortly after, not when libpq returns, so a new writer waits up to
// 3 s for the lock (the server's lock_timeout; measured: under ctest -j2 a
// writer opened right after the last one's drop was refused once). A second
// writer fails then with the first one's "pid N on host H". The row
// of `atlas_writer` (schema/009_atlas_writer) says how the last holder ended,
// 'running' when it died without mark_stopped(), as the lock file does.
//
// Brings the schema up to date first (the table must exist); refuses, as
// AtlasStore::open_postgres does, a database of another application or a newer
// schema before writing anything.
#include <memory>
#include <string>

namespace orbatlas {

class PgDb;

class PgWriterLock {
 public:
  // Error naming the holder when another writer has the lock. `shared`: a
  // replica of several: held together with the other replicas
  // (pg_advisory_lock_shared), refused only while a single writer has it; no
  // crash record (previous_holder_crashed() is false, mark_stopped() does nothing).
  explicit PgWriterLock(const std::string& conninfo, bool shared = false);
  ~PgWriterLock();  // releases the lock, then closes the connection
  PgWriterLock(const PgWriterLock&) = delete;
  PgWriterLock& operator=(const PgWriterLock&) = delete;

  bool previous_holder_crashed() const { return previous_crashed_; }
  void mark_stopped();

 private:
  std::unique_ptr<PgDb> db_;
  bool shared_ = false;
  bool previous_crashed_ = false;
};

}  // namespace orbatlas
