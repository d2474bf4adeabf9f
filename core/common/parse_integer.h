#pragma once
// Whole decimal text as an integer (table fields, path ids, query parameters,
// form fields): none for empty text, trailing characters, a sign an unsigned
// type cannot take, or a value out of the type's range. The caller words the error.
#include <charconv>
#include <optional>
#include <string_view>
#include <system_error>

namespace orbatlas {

template <class Integer>
std::optional<Integer> parse_integer(std::string_view text) {
  Integer value{};
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, value);
  if (text.empty() || ec != std::errc() || ptr != end) return std::nullopt;
  return value;
}

}  // namespace orbatlas
