#pragma once
// Timestamps are int64 nanoseconds everywhere (EuRoC's native unit). Text in
// seconds ("1403636580.838560") is converted exactly, digit by digit, never
// through a double, so a write -> read round trip keeps every nanosecond.
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace orbatlas {

using TimestampNs = std::int64_t;

constexpr TimestampNs kNsPerSecond = 1'000'000'000;

// Timestamps a live client may send: from the Unix epoch to 2100-01-01 UTC.
// A sensor clock counting from boot is inside; a value near INT64_MAX (which
// would wrap in differences and block every later frame) is not.
constexpr TimestampNs kMaxTimestampNs = 4'102'444'800 * kNsPerSecond;
inline bool is_valid_timestamp(TimestampNs t) { return t >= 0 && t <= kMaxTimestampNs; }
// "t_ns 123 is outside 0..kMaxTimestampNs (...)": the message of the refusal.
std::string invalid_timestamp_message(const std::string& what, TimestampNs t);

// "1403636580.83856" -> 1403636580838560000. Accepts an optional sign, up to 9
// fractional digits (more are rejected, not rounded). Empty optional on bad text.
std::optional<TimestampNs> parse_seconds_exact(std::string_view text);

// 1403636580838560000 -> "1403636580.838560000" (always 9 fractional digits).
std::string format_seconds_exact(TimestampNs t);

inline double ns_to_s(TimestampNs t) { return static_cast<double>(t) * 1e-9; }
inline TimestampNs s_to_ns(double s) { return static_cast<TimestampNs>(s * 1e9 + (s >= 0 ? 0.5 : -0.5)); }

}  // namespace orbatlas
