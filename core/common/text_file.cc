#include "core/common/text_file.h"

#include <zlib.h>

#include <charconv>
#include <memory>

#include "core/common/error.h"
#include "core/common/parse_integer.h"

namespace orbatlas {

std::string read_text_file(const std::filesystem::path& path) {
  // gzopen reads uncompressed files transparently.
  std::unique_ptr<gzFile_s, int (*)(gzFile)> file(gzopen(path.c_str(), "rb"), gzclose);
  if (!file) throw DataError("cannot open " + path.string());
  gzbuffer(file.get(), 1 << 17);
  std::string content;
  char buf[1 << 16];
  for (;;) {
    const int n = gzread(file.get(), buf, sizeof buf);
    if (n < 0) {
      int errnum = 0;
      throw DataError("cannot read " + path.string() + ": " + gzerror(file.get(), &errnum));
    }
    if (n == 0) break;
    content.append(buf, static_cast<std::size_t>(n));
  }
  return content;
}

void for_each_line(const std::filesystem::path& path, const std::function<void(const TextLine&)>& on_line) {
  const std::string content = read_text_file(path);
  std::size_t pos = 0;
  std::size_t number = 0;
  while (pos < content.size()) {
    std::size_t end = content.find('\n', pos);
    if (end == std::string::npos) end = content.size();
    std::size_t len = end - pos;
    if (len > 0 && content[pos + len - 1] == '\r') --len;
    on_line(TextLine{++number, std::string_view(content).substr(pos, len)});
    pos = end + 1;
  }
}

std::vector<std::string_view> split_fields(std::string_view line, std::string_view separators, bool skip_empty) {
  std::vector<std::string_view> out;
  std::size_t start = 0;
  for (;;) {
    const std::size_t end = line.find_first_of(separators, start);
    const std::string_view field =
        trim(line.substr(start, end == std::string_view::npos ? std::string_view::npos : end - start));
    if (!(skip_empty && field.empty())) out.push_back(field);
    if (end == std::string_view::npos) break;
    start = end + 1;
  }
  return out;
}

std::string_view trim(std::string_view s) {
  const auto first = s.find_first_not_of(" \t\r\n");
  if (first == std::string_view::npos) return {};
  const auto last = s.find_last_not_of(" \t\r\n");
  return s.substr(first, last - first + 1);
}

double parse_double(std::string_view field, const std::filesystem::path& path, std::size_t line) {
  double v = 0.0;
  const auto [ptr, ec] = std::from_chars(field.data(), field.data() + field.size(), v);
  if (ec != std::errc() || ptr != field.data() + field.size())
    throw DataError(path.string() + ":" + std::to_string(line) + ": not a number: '" + std::string(field) + "'");
  return v;
}

long long parse_int64(std::string_view field, const std::filesystem::path& path, std::size_t line) {
  const auto v = parse_integer<long long>(field);
  if (!v)
    throw DataError(path.string() + ":" + std::to_string(line) + ": not an integer: '" + std::string(field) + "'");
  return *v;
}

}  // namespace orbatlas
