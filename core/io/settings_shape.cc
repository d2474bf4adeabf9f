#include "core/io/settings_shape.h"

#include <algorithm>
#include <cctype>
#include <string>

#include "core/common/error.h"

namespace orbatlas {

void check_settings_shape(std::string_view text, const std::string& label) {
  const auto fail = [&](int number, const std::string& why) {
    throw DataError(label + ": malformed YAML: line " + std::to_string(number) + ": " + why);
  };
  const auto is_key_char = [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '.'; };
  const auto is_word_char = [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '.' || c == '+' || c == '-';
  };
  const auto is_number_list_char = [](char c) {
    return std::isdigit(static_cast<unsigned char>(c)) || c == '.' || c == ',' || c == '+' || c == '-' || c == 'e' ||
           c == 'E' || c == ' ' || c == '\t';
  };
  // The rest of a flow sequence from `at`: true when its ']' closes it on this line.
  const auto flow_sequence = [&](std::string_view rest, int number) {
    const std::size_t close = rest.find(']');
    const std::string_view inside = rest.substr(0, close);
    for (const char c : inside)
      if (!is_number_list_char(c)) fail(number, "a sequence holds numbers only");
    if (close == std::string_view::npos) return false;
    const std::string_view after = rest.substr(close + 1);
    const std::size_t next = after.find_first_not_of(" \t");
    if (next != std::string_view::npos && after[next] != '#') fail(number, "text after a sequence's ']'");
    return true;
  };
  bool open_sequence = false, in_matrix = false, seen_key = false, seen_directive = false;
  int number = 0;
  for (std::size_t start = 0; start <= text.size();) {
    const std::size_t end = std::min(text.find('\n', start), text.size());
    std::string_view line = text.substr(start, end - start);
    ++number;
    start = end + 1;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    if (open_sequence) {
      open_sequence = !flow_sequence(line, number);
      continue;
    }
    const std::size_t indent = line.find_first_not_of(" \t");
    if (indent == std::string_view::npos || line[indent] == '#') continue;
    std::string_view body = line.substr(indent);
    while (!body.empty() && (body.back() == ' ' || body.back() == '\t')) body.remove_suffix(1);
    if (body.front() == '%') {
      if (indent != 0 || seen_key || seen_directive || (body != "%YAML:1.0" && body != "%YAML 1.0"))
        fail(number, "the only directive is a first line \"%YAML:1.0\"");
      seen_directive = true;
      continue;
    }
    if (body == "---") {
      if (indent != 0 || seen_key) fail(number, "\"---\" comes before the first key");
      continue;
    }
    std::size_t k = 0;
    while (k < body.size() && is_key_char(body[k])) ++k;
    if (k == 0 || (!std::isalpha(static_cast<unsigned char>(body[0])) && body[0] != '_'))
      fail(number, "expected \"Key: value\"");
    std::size_t colon = k;
    while (colon < body.size() && (body[colon] == ' ' || body[colon] == '\t')) ++colon;
    if (colon >= body.size() || body[colon] != ':' ||
        (colon + 1 < body.size() && body[colon + 1] != ' ' && body[colon + 1] != '\t'))
      fail(number, "expected \"Key: value\" (a colon and a space after the key)");
    if (indent > 0 && !in_matrix) fail(number, "an indented key outside an !!opencv-matrix");
    if (indent == 0) in_matrix = false;
    seen_key = true;
    std::string_view value = colon + 1 < body.size() ? body.substr(colon + 1) : std::string_view();
    const std::size_t v = value.find_first_not_of(" \t");
    value = v == std::string_view::npos ? std::string_view() : value.substr(v);
    if (value.empty() || value.front() == '#') continue;
    if (value.front() == '[') {
      open_sequence = !flow_sequence(value.substr(1), number);
      continue;
    }
    if (value.front() == '"') {
      const std::size_t close = value.find('"', 1);
      if (close == std::string_view::npos) fail(number, "a quoted string without its closing quote");
      const std::size_t next = value.find_first_not_of(" \t", close + 1);
      if (next != std::string_view::npos && value[next] != '#') fail(number, "text after a quoted string");
      continue;
    }
    std::size_t w = 0;
    if (value.substr(0, 2) == "!!") w = 2;
    while (w < value.size() && is_word_char(value[w])) ++w;
    const std::size_t next = value.find_first_not_of(" \t", w);
    if (w == 0 || (next != std::string_view::npos && value[next] != '#'))
      fail(number, "a value is a number, a word, a quoted string, !!opencv-matrix or [numbers]");
    if (indent == 0 && value.substr(0, w) == "!!opencv-matrix") in_matrix = true;
  }
  if (open_sequence) fail(number, "a sequence's ']' is missing");
}

}  // namespace orbatlas
