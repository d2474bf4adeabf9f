#pragma once
// What the tar tests share: a fresh folder per test, files written and read
// whole, hand-made tar headers and entries (for what our writer refuses to
// produce), and the DataError message of an extraction.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <system_error>

#include "core/archive/tar_reader.h"
#include "core/common/error.h"

namespace orbatlas::test {

// A fresh folder per test, removed at the end.
class TempDir {
 public:
  TempDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = std::filesystem::temp_directory_path() /
            ("orbatlas_test_tar_" + std::to_string(::getpid()) + "_" + info->test_suite_name() + "_" + info->name());
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

inline void write_bytes(const std::filesystem::path& path, const std::string& bytes) {
  std::filesystem::create_directories(path.parent_path());
  std::ofstream(path, std::ios::binary) << bytes;
}

inline std::string read_bytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// Hand-made headers, for entries our writer refuses to produce.
inline std::string raw_header(const std::string& name, char type, std::uint64_t size, const std::string& linkname = "",
                              bool base256_size = false) {
  std::string h(512, '\0');
  h.replace(0, name.size(), name);
  std::snprintf(&h[100], 8, "%07o", 0644u);
  std::snprintf(&h[124], 12, "%011llo", static_cast<unsigned long long>(size));
  if (base256_size) {
    h.replace(124, 12, std::string(12, '\0'));
    h[124] = static_cast<char>(0x80);
    for (int i = 0; i < 8; ++i) h[135 - i] = static_cast<char>((size >> (8 * i)) & 0xff);
  }
  std::snprintf(&h[136], 12, "%011o", 0u);
  h[156] = type;
  h.replace(157, linkname.size(), linkname);
  h.replace(257, 8, std::string("ustar", 6) + "00");  // POSIX magic and version
  h.replace(148, 8, std::string(8, ' '));
  unsigned sum = 0;
  for (char c : h) sum += static_cast<unsigned char>(c);
  std::snprintf(&h[148], 8, "%06o", sum);
  return h;
}

inline std::string raw_entry(const std::string& name, char type, const std::string& data,
                             const std::string& linkname = "") {
  return raw_header(name, type, data.size(), linkname) + data + std::string((512 - data.size() % 512) % 512, '\0');
}

inline const std::string kEnd(1024, '\0');

inline std::string error_of(const std::filesystem::path& tar, const std::filesystem::path& destination,
                            const TarLimits& limits = {}) {
  try {
    extract_tar(tar, destination, limits);
  } catch (const DataError& e) {
    return e.what();
  }
  return "<no DataError>";
}

}  // namespace orbatlas::test

#define EXPECT_CONTAINS(text, word) EXPECT_NE(std::string(text).find(word), std::string::npos) << (text)
