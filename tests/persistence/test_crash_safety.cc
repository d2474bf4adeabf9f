// Crash safety of checkpoints: a writer process (orbatlas_crash_writer) builds a
// deterministic evolving atlas and checkpoints every state k; it is killed with
// SIGKILL at random moments, many of them inside a checkpoint's transaction.
// Each time, the file must pass SQLite's integrity check, open, and load into
// exactly the state k_db its checkpoint sequence names, with k_db the last state
// the writer acknowledged or the one after (committed, not yet acknowledged).
// The same on PostgreSQL: the writer checkpoints into a fresh
// database of a throwaway cluster per kill, whose server sees the connection
// die and rolls the open transaction back.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <random>
#include <string>
#include <thread>

#include "core/persistence/atlas_store.h"
#include "core/persistence/sqlite_db.h"
#include "tests/support/persistence_backends.h"
#include "tests/persistence/test_crash_safety_model.h"
#include "tests/persistence/test_persistence_expect.h"
#include "tests/persistence/test_persistence_random_atlas.h"

extern char** environ;

namespace orbatlas {
namespace {

using namespace test;  // NOLINT: the shared helpers of the persistence tests
using Clock = std::chrono::steady_clock;

constexpr const char* kVocabularyHash = "crash-safety-test";  // as the writer's
constexpr int kSteps = 12;
constexpr int kIterations = 36;
constexpr int kPostgresIterations = 12;  // a fresh database each: creating one takes ~0.1 s

// The writer process, its stdout read line by line.
class Writer {
 public:
  Writer(const std::string& db, int steps) {
    int fds[2];
    if (::pipe2(fds, O_CLOEXEC) != 0) throw std::runtime_error("pipe2 failed");
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, fds[1], STDOUT_FILENO);  // dup2 clears O_CLOEXEC
    std::string program = ORBATLAS_CRASH_WRITER, path = db, count = std::to_string(steps);
    char* argv[] = {program.data(), path.data(), count.data(), nullptr};
    const int rc = posix_spawn(&pid_, program.c_str(), &actions, nullptr, argv, environ);
    posix_spawn_file_actions_destroy(&actions);
    ::close(fds[1]);
    fd_ = fds[0];
    if (rc != 0) throw std::runtime_error("cannot start " + program);
  }
  ~Writer() {
    kill();
    ::close(fd_);
  }

  // The next line, or none at the deadline or at the end of the output.
  std::optional<std::string> next_line(Clock::time_point deadline) {
    while (true) {
      if (const auto end = buffer_.find('\n'); end != std::string::npos) {
        std::string line = buffer_.substr(0, end);
        buffer_.erase(0, end + 1);
        return line;
      }
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
      if (left <= 0 || eof_) return std::nullopt;
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, static_cast<int>(left)) <= 0) continue;
      char chunk[256];
      const ssize_t n = ::read(fd_, chunk, sizeof chunk);
      if (n <= 0) {
        eof_ = true;
      } else {
        buffer_.append(chunk, static_cast<std::size_t>(n));
      }
    }
  }

  // SIGKILL (if still running) and reap; true when it had already exited.
  bool kill() {
    if (pid_ <= 0) return exited_;
    int status = 0;
    exited_ = ::waitpid(pid_, &status, WNOHANG) == pid_;
    if (!exited_) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, &status, 0);
    } else {
      EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "the writer failed on its own";
    }
    pid_ = -1;
    return exited_;
  }

 private:
  pid_t pid_ = -1;
  int fd_ = -1;
  std::string buffer_;
  bool eof_ = false;
  bool exited_ = false;
};

struct Events {
  int acknowledged = 0;         // last "C k"
  bool in_transaction = false;  // the last event was "B k" (no "C k" after it)
  void add(const std::string& line) {
    int k = 0;
    char event = 0;
    if (std::sscanf(line.c_str(), "%c %d", &event, &k) != 2) return;
    if (event == 'C') acknowledged = k;
    in_transaction = event == 'B';
  }
};

class CrashSafety : public AtlasBackendTest {};
ORBATLAS_PERSISTENCE_BACKENDS(CrashSafety);

TEST_P(CrashSafety, KilledCheckpointWriterLeavesTheLastCommittedState) {
  std::mt19937_64 rng(20240607);
  int mid_transaction = 0;
  const int iterations = backend() == SqlDialect::kSqlite ? kIterations : kPostgresIterations;
  for (int iteration = 0; iteration < iterations; ++iteration) {
    SCOPED_TRACE("iteration " + std::to_string(iteration));
    const std::string db = another_location("crash_" + std::to_string(iteration));
    Events events;
    {
      Writer writer(db, kSteps);
      if (iteration % 3 == 0) {
        // Any moment: from start-up to after the last step.
        const auto kill_at = Clock::now() + std::chrono::microseconds(rng() % 900'000);
        while (const auto line = writer.next_line(kill_at)) events.add(*line);
      } else {
        // Right after the writer announced the transaction of a random state, a
        // random part of a transaction's duration later.
        const int target = 1 + static_cast<int>(rng() % kSteps);
        const auto give_up = Clock::now() + std::chrono::seconds(20);
        while (const auto line = writer.next_line(give_up)) {
          events.add(*line);
          if (line->starts_with("B ") && std::stoi(line->substr(2)) >= target) break;
        }
        std::this_thread::sleep_for(std::chrono::microseconds(rng() % 40'000));
      }
      writer.kill();
      while (const auto line = writer.next_line(Clock::now() + std::chrono::seconds(5))) events.add(*line);
    }
    if (events.in_transaction) ++mid_transaction;

    // What the file says.
    std::int64_t k_db = 0;
    if (backend() == SqlDialect::kSqlite && std::filesystem::exists(db)) {
      SqliteDb raw(db);  // recovers the WAL of the killed writer
      SqliteStatement check = raw.prepare("PRAGMA integrity_check");
      ASSERT_TRUE(check.step());
      EXPECT_EQ(check.text(0), "ok");
    }
    AtlasStore store = AtlasStore::open(db, kVocabularyHash);
    k_db = store.checkpoint_sequence();
    EXPECT_GE(k_db, events.acknowledged);
    EXPECT_LE(k_db, events.acknowledged + 1);
    Atlas loaded;
    store.load_atlas(loaded, nullptr);
    Atlas expected;
    build_crash_state(expected, static_cast<int>(k_db));
    expect_atlas_eq(expected, loaded, false);
    if (HasFailure()) return;
  }
  // The test must exercise what it is about.
  EXPECT_GT(mid_transaction, 0) << "in " << iterations << " runs of the writer";
}

}  // namespace
}  // namespace orbatlas
