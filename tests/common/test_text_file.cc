#include <gtest/gtest.h>
#include <zlib.h>

#include <filesystem>
#include <fstream>

#include "core/common/error.h"
#include "core/common/text_file.h"

namespace orbatlas {
namespace {

std::filesystem::path temp_file(const std::string& name) {
  return std::filesystem::temp_directory_path() / ("orbatlas_test_text_" + std::to_string(::getpid()) + "_" + name);
}

TEST(TextFile, ReadsPlainAndGzipLinesWithNumbers) {
  const std::string content = "# header\r\n1 2 3\n\nlast line without newline";
  const auto plain = temp_file("plain.txt"), gz = temp_file("packed.txt.gz");
  std::ofstream(plain, std::ios::binary) << content;
  gzFile f = gzopen(gz.c_str(), "wb");
  ASSERT_NE(f, nullptr);
  gzwrite(f, content.data(), static_cast<unsigned>(content.size()));
  gzclose(f);
  for (const auto& path : {plain, gz}) {
    std::vector<std::pair<std::size_t, std::string>> lines;
    for_each_line(path, [&](const TextLine& l) { lines.emplace_back(l.number, std::string(l.text)); });
    ASSERT_EQ(lines.size(), 4u) << path;
    EXPECT_EQ(lines[0].second, "# header");  // CR removed
    EXPECT_EQ(lines[1].second, "1 2 3");
    EXPECT_EQ(lines[2].second, "");
    EXPECT_EQ(lines[3], std::make_pair(std::size_t{4}, std::string("last line without newline")));
  }
  std::filesystem::remove(plain);
  std::filesystem::remove(gz);
}

TEST(TextFile, MissingFileIsADataError) { EXPECT_THROW(read_text_file("/nonexistent/orbatlas/file.txt"), DataError); }

TEST(TextFile, SplitsAndParsesWithContext) {
  const auto f = split_fields(" 1.5,  2 ,,x", ",", false);
  ASSERT_EQ(f.size(), 4u);
  EXPECT_EQ(f[0], "1.5");
  EXPECT_EQ(f[2], "");
  EXPECT_EQ(split_fields("a  b\tc", " \t", true).size(), 3u);
  EXPECT_DOUBLE_EQ(parse_double("1.5", "f", 1), 1.5);
  EXPECT_EQ(parse_int64("-42", "f", 1), -42);
  try {
    parse_double("1.5x", "data.csv", 7);
    FAIL() << "expected DataError";
  } catch (const DataError& e) {
    EXPECT_NE(std::string(e.what()).find("data.csv:7"), std::string::npos) << e.what();
  }
  EXPECT_THROW(parse_int64("1.0", "f", 1), DataError);
}

}  // namespace
}  // namespace orbatlas
