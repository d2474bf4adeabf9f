#include <gtest/gtest.h>

#include "core/common/timestamp.h"

namespace orbatlas {
namespace {

TEST(Timestamp, ParsesSecondsExactly) {
  EXPECT_EQ(parse_seconds_exact("1403636580.83856"), 1403636580838560000LL);
  EXPECT_EQ(parse_seconds_exact("1403636580.838560123"), 1403636580838560123LL);
  EXPECT_EQ(parse_seconds_exact("1403636580"), 1403636580000000000LL);
  EXPECT_EQ(parse_seconds_exact("0.000000001"), 1);
  EXPECT_EQ(parse_seconds_exact("-1.5"), -1500000000LL);
  EXPECT_EQ(parse_seconds_exact(".5"), 500000000LL);
  EXPECT_EQ(parse_seconds_exact("2.1234567890"), 2123456789LL);  // trailing zero past ns is fine
}

TEST(Timestamp, RejectsBadText) {
  EXPECT_FALSE(parse_seconds_exact("").has_value());
  EXPECT_FALSE(parse_seconds_exact("abc").has_value());
  EXPECT_FALSE(parse_seconds_exact("1.2.3").has_value());
  EXPECT_FALSE(parse_seconds_exact("1e9").has_value());
  EXPECT_FALSE(parse_seconds_exact("1.0000000001").has_value()) << "sub-nanosecond digits must not be rounded away";
  EXPECT_FALSE(parse_seconds_exact("99999999999999999999").has_value()) << "overflow";
}

TEST(Timestamp, FormatRoundTripsEveryNanosecond) {
  for (const TimestampNs t : {0LL, 1LL, 999999999LL, 1403636580838560123LL, -1500000000LL, -1LL}) {
    const std::string text = format_seconds_exact(t);
    EXPECT_EQ(parse_seconds_exact(text), t) << text;
  }
  EXPECT_EQ(format_seconds_exact(1403636580838560000LL), "1403636580.838560000");
  EXPECT_EQ(format_seconds_exact(-1), "-0.000000001");
}

}  // namespace
}  // namespace orbatlas
