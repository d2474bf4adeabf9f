#pragma once
// A test that needs something a machine may lack (PostgreSQL, Chromium, GNU tar,
// the real EuRoC data beside the checkout) skips with the reason on a user's
// fresh clone. Under ORBATLAS_REQUIRE=all, which .ci/run sets, the same absence
// fails the test with the reason: a broken install step cannot pass unnoticed.
#include <gtest/gtest.h>

#include <cstdlib>
#include <string_view>

namespace orbatlas::test {

inline bool everything_is_required() {
  const char* value = std::getenv("ORBATLAS_REQUIRE");
  return value != nullptr && std::string_view(value) == "all";
}

}  // namespace orbatlas::test

// Skips the test (or fails it, under ORBATLAS_REQUIRE=all) saying what is missing.
// `reason` is anything a gtest message takes (`"x is missing: " << why`).
#define ORBATLAS_NEEDS(reason)                                                  \
  do {                                                                          \
    if (::orbatlas::test::everything_is_required()) {                           \
      FAIL() << "ORBATLAS_REQUIRE=all, but " << reason;                         \
    } else {                                                                    \
      GTEST_SKIP() << reason << " (ORBATLAS_REQUIRE=all would fail this test)"; \
    }                                                                           \
  } while (0)
