// WorkerErrors: errors a worker contains are counted with the last message; a
// run of fatal_after failures in a row (and only that) becomes a WorkerFailed.
#include <gtest/gtest.h>

#include <stdexcept>

#include "core/common/worker_errors.h"

namespace orbatlas {
namespace {

std::exception_ptr error(const char* what) { return std::make_exception_ptr(std::runtime_error(what)); }

TEST(WorkerErrors, CountsAndKeepsTheLastMessage) {
  WorkerErrors errors("test worker", 3);
  EXPECT_EQ(errors.counts().errors, 0u);
  EXPECT_FALSE(errors.record("unit 1", error("first")));
  errors.succeeded();
  EXPECT_FALSE(errors.record("unit 2", error("second")));
  EXPECT_FALSE(errors.record("unit 3", error("third")));
  errors.succeeded();  // the run of failures starts again
  EXPECT_FALSE(errors.record("unit 4", error("fourth")));
  const WorkerErrorCounts counts = errors.counts();
  EXPECT_EQ(counts.errors, 4u);
  EXPECT_EQ(counts.last, "fourth");
  EXPECT_FALSE(counts.fatal);
  EXPECT_EQ(errors.fatal_error(), nullptr);
}

TEST(WorkerErrors, ARunOfFailuresBecomesFatal) {
  WorkerErrors errors("test worker", 3);
  EXPECT_FALSE(errors.record("a", error("x")));
  EXPECT_FALSE(errors.record("b", error("y")));
  EXPECT_TRUE(errors.record("c", error("z")));
  EXPECT_TRUE(errors.counts().fatal);
  ASSERT_NE(errors.fatal_error(), nullptr);
  try {
    std::rethrow_exception(errors.fatal_error());
  } catch (const WorkerFailed& e) {
    EXPECT_STREQ(e.what(), "test worker failed 3 times in a row; last: z");
  }
  errors.succeeded();  // once fatal, it stays so
  EXPECT_TRUE(errors.record("d", error("w")));
}

TEST(WorkerErrors, ANonStandardExceptionIsCountedToo) {
  WorkerErrors errors("test worker");
  EXPECT_FALSE(errors.record("unit", std::make_exception_ptr(42)));
  EXPECT_EQ(errors.counts().last, "an unknown error");
}

}  // namespace
}  // namespace orbatlas
