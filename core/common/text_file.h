#pragma once
// Reading text data files line by line, plain or gzip-compressed (detected from
// the content, not the name), with the file name and line number for errors.
#include <cstddef>
#include <filesystem>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

namespace orbatlas {

struct TextLine {
  std::size_t number = 0;  // 1-based line number
  std::string_view text;   // without the line terminator ("\r\n" or "\n")
};

// Calls on_line for every line. Throws DataError if the file cannot be opened or read.
void for_each_line(const std::filesystem::path& path, const std::function<void(const TextLine&)>& on_line);

// Whole content (decompressed if gzip).
std::string read_text_file(const std::filesystem::path& path);

// Splits on any of the separator characters, dropping empty fields when
// skip_empty is set (for runs of spaces).
std::vector<std::string_view> split_fields(std::string_view line, std::string_view separators, bool skip_empty);

std::string_view trim(std::string_view s);

// Parses a number, throwing DataError with "<path>:<line>: ..." context on failure.
double parse_double(std::string_view field, const std::filesystem::path& path, std::size_t line);
long long parse_int64(std::string_view field, const std::filesystem::path& path, std::size_t line);

}  // namespace orbatlas
