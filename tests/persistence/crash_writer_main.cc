// Helper program of the crash-safety test (test_persistence): builds the deterministic evolving atlas
// (test_crash_safety_model.h) and checkpoints it after every step k, reporting
// on stdout, unbuffered, one line per event:
//   "B k"  a checkpoint of state k is about to open its write transaction
//   "C k"  the checkpoint of state k has committed
// The test kills it with SIGKILL at random moments.
//
// Usage: orbatlas_crash_writer <database> <steps>
#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <exception>

#include "core/persistence/atlas_checkpointer.h"
#include "tests/persistence/test_crash_safety_model.h"

namespace {

// The vocabulary hash is only checked for equality; no BoW is computed here.
constexpr const char* kVocabularyHash = "crash-safety-test";

void report(char event, int k) {
  char line[32];
  const int n = std::snprintf(line, sizeof line, "%c %d\n", event, k);
  // write(2), not stdio: the line must be in the pipe before the next step.
  if (::write(STDOUT_FILENO, line, static_cast<std::size_t>(n)) != n) std::_Exit(3);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: %s <database> <steps>\n", argv[0]);
    return 2;
  }
  try {
    const int steps = std::atoi(argv[2]);
    orbatlas::Atlas atlas;
    std::atomic<int> step{0}, committed{0};
    orbatlas::CheckpointOptions options;
    options.every_keyframes = 0;  // only checkpoint_now: one checkpoint per state
    options.every_seconds = 0;
    options.before_transaction = [&] {
      // Not for the final checkpoint of stop(), which has nothing left to write.
      if (step.load() > committed.load()) report('B', step.load());
    };
    orbatlas::AtlasCheckpointer checkpointer(atlas, argv[1], kVocabularyHash, options);
    for (int k = 1; k <= steps; ++k) {
      orbatlas::test::apply_crash_step(atlas, k);
      step.store(k);
      if (!checkpointer.checkpoint_now()) {
        std::fprintf(stderr, "checkpoint %d failed: %s\n", k, checkpointer.stats().last_error.c_str());
        return 1;
      }
      committed.store(k);
      report('C', k);
    }
    checkpointer.stop();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
  return 0;
}
