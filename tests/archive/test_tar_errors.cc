// What tar extraction refuses, writing nothing outside its destination:
// '..' and absolute names, damaged and truncated archives, what is no tar,
// limits, symlink escapes, unsafe long names; and what the reader skips
// (links, special entries) or reads (pax, GNU and base-256 records).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "core/archive/tar_reader.h"
#include "core/common/error.h"
#include "tests/support/tar_test_files.h"

namespace orbatlas {
namespace {

namespace fs = std::filesystem;
using test::error_of;
using test::kEnd;
using test::raw_entry;
using test::raw_header;
using test::read_bytes;
using test::TempDir;
using test::write_bytes;

// The archive sits beside "dest" in a sandbox; nothing but dest may appear there.
struct Sandbox {
  TempDir tmp;
  fs::path archive = tmp.path() / "in.tar", dest = tmp.path() / "dest";
  void write(const std::string& bytes) const { write_bytes(archive, bytes); }
  void expect_nothing_outside_dest() const {
    for (const auto& e : fs::directory_iterator(tmp.path()))
      EXPECT_TRUE(e.path() == archive || e.path() == dest) << "written outside the destination: " << e.path();
  }
};

TEST(TarErrors, DotDotEntryIsRefused) {
  Sandbox box;
  box.write(raw_entry("good.txt", '0', "ok") + raw_entry("../evil", '0', "evil") + kEnd);
  const std::string message = error_of(box.archive, box.dest);
  EXPECT_CONTAINS(message, "'..'");
  EXPECT_CONTAINS(message, "../evil");
  box.expect_nothing_outside_dest();
  box.write(raw_entry("a/b/../../../evil", '0', "evil") + kEnd);
  EXPECT_CONTAINS(error_of(box.archive, box.dest), "'..'");
  box.expect_nothing_outside_dest();
}

TEST(TarErrors, AbsolutePathIsRefused) {
  Sandbox box;
  box.write(raw_entry("/etc/x", '0', "evil") + kEnd);
  EXPECT_CONTAINS(error_of(box.archive, box.dest), "absolute path");
  const fs::path outside = box.tmp.path() / "abs_evil";
  box.write(raw_entry(outside.string(), '0', "evil") + kEnd);
  EXPECT_CONTAINS(error_of(box.archive, box.dest), "absolute path");
  EXPECT_FALSE(fs::exists(outside));
  box.expect_nothing_outside_dest();
}

TEST(TarErrors, CorruptedChecksumIsRefused) {
  Sandbox box;
  std::string bytes = raw_entry("a.txt", '0', "first") + raw_entry("b.txt", '0', "second") + kEnd;
  bytes[1024 + 150] ^= 1;  // a digit of the second header's checksum
  box.write(bytes);
  const std::string message = error_of(box.archive, box.dest);
  EXPECT_CONTAINS(message, "damaged header");
  EXPECT_CONTAINS(message, "1024");  // where
  EXPECT_FALSE(fs::exists(box.dest / "b.txt"));
  box.expect_nothing_outside_dest();
}

TEST(TarErrors, TruncatedArchiveIsRefused) {
  Sandbox box;
  const std::string full =
      raw_entry("a.txt", '0', "first") + raw_entry("big.bin", '0', std::string(10'000, 'x')) + kEnd;
  box.write(full.substr(0, 1024 + 512 + 4'000));  // cut inside big.bin's data
  std::string message = error_of(box.archive, box.dest);
  EXPECT_CONTAINS(message, "truncated");
  EXPECT_CONTAINS(message, "big.bin");
  box.write(full.substr(0, full.size() - kEnd.size()));  // cut at an entry boundary
  EXPECT_CONTAINS(error_of(box.archive, box.dest), "truncated");
  box.write(full.substr(0, 700));  // cut inside a header
  EXPECT_CONTAINS(error_of(box.archive, box.dest), "truncated");
  box.expect_nothing_outside_dest();
}

TEST(TarErrors, NonTarFileIsRefused) {
  Sandbox box;
  std::string png = "\x89PNG\r\n\x1a\n";
  png += std::string("\0\0\0\x0dIHDR", 8) + std::string(3000, '\x42');
  box.write(png);
  EXPECT_CONTAINS(error_of(box.archive, box.dest), "not a tar archive");
  box.write("");
  EXPECT_CONTAINS(error_of(box.archive, box.dest), "not a tar archive");
  box.write("short");
  EXPECT_CONTAINS(error_of(box.archive, box.dest), "not a tar archive");
  box.write(std::string("\x1f\x8b\x08\x00", 4) + std::string(1000, '\x01'));
  EXPECT_CONTAINS(error_of(box.archive, box.dest), "gzip");
  box.expect_nothing_outside_dest();
}

TEST(TarErrors, LimitsAreEnforced) {
  Sandbox box;
  std::string five;
  for (char i = '0'; i < '5'; ++i) five += raw_entry(std::string{'f', i}, '0', std::string(100, 'x'));
  box.write(raw_entry("big.bin", '0', std::string(1000, 'x')) + five + kEnd);
  TarLimits limits;
  limits.max_file_bytes = 999;
  std::string message = error_of(box.archive, box.dest, limits);
  EXPECT_CONTAINS(message, "max_file_bytes");
  EXPECT_CONTAINS(message, "big.bin");
  EXPECT_FALSE(fs::exists(box.dest / "big.bin"));

  box.write(five + kEnd);
  limits = {};
  limits.max_entries = 3;
  message = error_of(box.archive, box.dest, limits);
  EXPECT_CONTAINS(message, "too many entries");
  EXPECT_FALSE(fs::exists(box.dest / "f3"));
  limits.max_entries = 5;
  EXPECT_EQ(extract_tar(box.archive, box.dest, limits).files, 5u);  // exactly at the limit

  limits = {};
  limits.max_total_bytes = 450;
  EXPECT_CONTAINS(error_of(box.archive, box.dest, limits), "max_total_bytes");
  box.expect_nothing_outside_dest();
}

TEST(TarReader, LinksAndSpecialEntriesAreSkippedAndReported) {
  Sandbox box;
  box.write(raw_entry("mav0/", '5', "") + raw_entry("mav0/link", '2', "", "/etc/passwd") +
            raw_entry("mav0/hard", '1', "", "mav0/data.csv") + raw_entry("mav0/data.csv", '0', "1,2\n") +
            raw_entry("mav0/fifo", '6', "") + raw_entry("label", 'V', "") + kEnd);
  const TarExtractReport report = extract_tar(box.archive, box.dest);
  EXPECT_EQ(report.files, 1u);
  EXPECT_EQ(report.directories, 1u);
  EXPECT_EQ(report.skipped, 3u);  // a GNU volume label is no entry at all for libarchive
  ASSERT_EQ(report.skipped_names.size(), 3u);
  EXPECT_EQ(report.skipped_names[0], "mav0/link (symlink)");
  EXPECT_EQ(report.skipped_names[1], "mav0/hard (hard link)");
  EXPECT_EQ(report.skipped_names[2], "mav0/fifo (fifo)");
  EXPECT_FALSE(fs::exists(fs::symlink_status(box.dest / "mav0/link")));
  EXPECT_FALSE(fs::exists(fs::symlink_status(box.dest / "mav0/hard")));
  EXPECT_FALSE(fs::exists(fs::symlink_status(box.dest / "mav0/fifo")));
  EXPECT_FALSE(fs::exists(box.dest / "label"));
  EXPECT_EQ(read_bytes(box.dest / "mav0/data.csv"), "1,2\n");
  box.expect_nothing_outside_dest();
}

// A symlink in the archive is skipped, so a later entry "through" it lands in a
// plain directory of the destination; a symlink already in the destination is
// never written through.
TEST(TarErrors, SymlinkEscapesAreImpossible) {
  Sandbox box;
  const fs::path outside = box.tmp.path() / "outside";
  box.write(raw_entry("escape", '2', "", outside.string()) + raw_entry("escape/evil.txt", '0', "evil") + kEnd);
  const TarExtractReport report = extract_tar(box.archive, box.dest);
  EXPECT_EQ(report.skipped, 1u);
  EXPECT_TRUE(fs::is_directory(fs::symlink_status(box.dest / "escape")));
  EXPECT_EQ(read_bytes(box.dest / "escape/evil.txt"), "evil");
  EXPECT_FALSE(fs::exists(outside));

  fs::create_directories(outside);
  fs::create_directory_symlink(outside, box.dest / "planted");
  box.write(raw_entry("planted/evil.txt", '0', "evil") + kEnd);
  EXPECT_CONTAINS(error_of(box.archive, box.dest), "symlink");
  fs::create_symlink(outside / "file.txt", box.dest / "planted_file");
  box.write(raw_entry("planted_file", '0', "evil") + kEnd);
  EXPECT_CONTAINS(error_of(box.archive, box.dest), "symlink");
  EXPECT_TRUE(fs::is_empty(outside));
  fs::remove(box.dest / "planted");
  fs::remove(box.dest / "planted_file");
  fs::remove_all(outside);
  box.expect_nothing_outside_dest();
}

// Names from pax and GNU long-name records are checked like header names.
TEST(TarErrors, UnsafeLongNamesAreRefused) {
  Sandbox box;
  const std::string pax_record = "19 path=../../evil\n";
  box.write(raw_entry("PaxHeaders/x", 'x', pax_record) + raw_entry("innocent.txt", '0', "evil") + kEnd);
  std::string message = error_of(box.archive, box.dest);
  EXPECT_CONTAINS(message, "'..'");
  EXPECT_CONTAINS(message, "../../evil");
  box.write(raw_entry("././@LongLink", 'L', "/tmp/orbatlas_absolute_evil" + std::string(1, '\0')) +
            raw_entry("innocent.txt", '0', "evil") + kEnd);
  EXPECT_CONTAINS(error_of(box.archive, box.dest), "absolute path");
  EXPECT_FALSE(fs::exists("/tmp/orbatlas_absolute_evil"));
  box.expect_nothing_outside_dest();
  // Names the file system cannot take: a DataError (422 for an upload), not an
  // error of the server's (500).
  const std::string long_part(300, 'n');
  box.write(raw_entry("././@LongLink", 'L', "a/" + long_part + std::string(1, '\0')) +
            raw_entry("innocent.txt", '0', "x") + kEnd);
  message = error_of(box.archive, box.dest);
  EXPECT_CONTAINS(message, "a path component of 300 bytes");
  EXPECT_LT(message.size(), 600u) << "the whole name in the message";
  std::string deep;
  for (int i = 0; i < 400; ++i) deep += "dddddddddd/";
  box.write(raw_entry("././@LongLink", 'L', deep + "f" + std::string(1, '\0')) + raw_entry("innocent.txt", '0', "x") +
            kEnd);
  EXPECT_CONTAINS(error_of(box.archive, box.dest), "at most 3000");
}

TEST(TarReader, PaxGnuBase256AndDotPrefixes) {
  Sandbox box;
  const std::string long_name = "mav0/" + std::string(150, 'l') + ".txt";
  const std::string pax_record = std::to_string(long_name.size() + 10) + " path=" + long_name + "\n";
  ASSERT_EQ(pax_record.size(), long_name.size() + 10);  // "NNN path=...\n"
  std::string bytes = raw_entry("pax_global_header", 'g', "19 comment=ignored\n") +
                      raw_entry("./PaxHeaders/x", 'x', pax_record) + raw_entry("truncated_name", '0', "from pax") +
                      raw_entry("././@LongLink", 'L', std::string(120, 'q') + '\0') + raw_entry("q", '0', "from L") +
                      raw_header("./sized.bin", '0', 5, "", true) + "12345" + std::string(507, '\0') +
                      raw_entry("./", '5', "") + raw_entry(".//mav0//./x.txt", '0', "x") +
                      raw_entry("PaxHeaders/sz", 'x', "10 size=3\n") + raw_header("pax_size.txt", '0', 0) + "abc" +
                      std::string(509, '\0') + kEnd;
  box.write(bytes);
  const TarExtractReport report = extract_tar(box.archive, box.dest);
  EXPECT_EQ(read_bytes(box.dest / long_name), "from pax");
  EXPECT_EQ(read_bytes(box.dest / std::string(120, 'q')), "from L");
  EXPECT_EQ(read_bytes(box.dest / "sized.bin"), "12345");
  EXPECT_EQ(read_bytes(box.dest / "mav0/x.txt"), "x");
  EXPECT_EQ(read_bytes(box.dest / "pax_size.txt"), "abc");  // the pax size overrides the header's 0
  EXPECT_FALSE(fs::exists(box.dest / "truncated_name"));
  EXPECT_FALSE(fs::exists(box.dest / "q"));
  EXPECT_EQ(report.files, 5u);
  EXPECT_EQ(report.skipped, 0u);

  box.write(kEnd);  // an empty archive
  const TarExtractReport empty = extract_tar(box.archive, box.tmp.path() / "dest" / "empty");
  EXPECT_EQ(empty.files + empty.directories + empty.skipped, 0u);
  EXPECT_TRUE(fs::is_directory(box.dest / "empty"));
  box.expect_nothing_outside_dest();
}

}  // namespace
}  // namespace orbatlas
