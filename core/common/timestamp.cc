#include "core/common/timestamp.h"

#include <cstdio>
#include <limits>

namespace orbatlas {

std::optional<TimestampNs> parse_seconds_exact(std::string_view text) {
  if (text.empty()) return std::nullopt;
  bool negative = false;
  std::size_t i = 0;
  if (text[0] == '-' || text[0] == '+') {
    negative = text[0] == '-';
    i = 1;
  }
  std::int64_t whole = 0;
  std::size_t whole_digits = 0;
  for (; i < text.size() && text[i] >= '0' && text[i] <= '9'; ++i, ++whole_digits) {
    if (whole > (std::numeric_limits<std::int64_t>::max() / kNsPerSecond - 9) / 10) return std::nullopt;
    whole = whole * 10 + (text[i] - '0');
  }
  std::int64_t frac = 0;
  int frac_digits = 0;
  if (i < text.size() && text[i] == '.') {
    ++i;
    for (; i < text.size() && text[i] >= '0' && text[i] <= '9'; ++i) {
      if (frac_digits == 9) {
        if (text[i] != '0') return std::nullopt;  // sub-nanosecond precision: reject
        continue;
      }
      frac = frac * 10 + (text[i] - '0');
      ++frac_digits;
    }
  }
  if (i != text.size() || (whole_digits == 0 && frac_digits == 0)) return std::nullopt;
  for (int d = frac_digits; d < 9; ++d) frac *= 10;
  const std::int64_t value = whole * kNsPerSecond + frac;
  return negative ? -value : value;
}

std::string format_seconds_exact(TimestampNs t) {
  const bool negative = t < 0;
  const std::uint64_t a = negative ? static_cast<std::uint64_t>(-(t + 1)) + 1 : static_cast<std::uint64_t>(t);
  char buf[48];
  std::snprintf(buf, sizeof buf, "%s%llu.%09llu", negative ? "-" : "",
                static_cast<unsigned long long>(a / kNsPerSecond), static_cast<unsigned long long>(a % kNsPerSecond));
  return buf;
}

std::string invalid_timestamp_message(const std::string& what, TimestampNs t) {
  return what + " " + std::to_string(t) + " ns is outside 0.." + std::to_string(kMaxTimestampNs) +
         " (nanoseconds since the Unix epoch or since the sensor started, before the year 2100)";
}

}  // namespace orbatlas
