#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <string>

#include "core/archive/tar_reader.h"
#include "core/archive/tar_stream_extractor.h"
#include "core/archive/tar_writer.h"
#include "core/common/error.h"
#include "tests/support/requirement.h"

namespace orbatlas {
namespace {

namespace fs = std::filesystem;

// A fresh folder per test, removed at the end.
class TempDir {
 public:
  TempDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = fs::temp_directory_path() /
            ("orbatlas_test_tar_" + std::to_string(::getpid()) + "_" + info->test_suite_name() + "_" + info->name());
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

void write_bytes(const fs::path& path, const std::string& bytes) {
  fs::create_directories(path.parent_path());
  std::ofstream(path, std::ios::binary) << bytes;
}

std::string read_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// Regular files (relative path -> content) and directories of a tree.
struct Tree {
  std::map<std::string, std::string> files;
  std::set<std::string> directories;
};

Tree read_tree(const fs::path& root) {
  Tree t;
  for (const auto& e : fs::recursive_directory_iterator(root)) {
    const std::string rel = e.path().lexically_relative(root).generic_string();
    if (e.is_symlink()) continue;
    if (e.is_directory())
      t.directories.insert(rel);
    else if (e.is_regular_file())
      t.files[rel] = read_bytes(e.path());
  }
  return t;
}

void expect_same_tree(const fs::path& expected, const fs::path& actual) {
  const Tree a = read_tree(expected), b = read_tree(actual);
  EXPECT_EQ(a.directories, b.directories);
  ASSERT_EQ(a.files.size(), b.files.size());
  for (const auto& [path, content] : a.files) {
    const auto it = b.files.find(path);
    ASSERT_NE(it, b.files.end()) << "missing " << path;
    EXPECT_TRUE(it->second == content) << "content differs: " << path;
  }
}

// A sample recording: nested folders, binary, empty and long-named files. Returns
// the root (the folder that contains mav0/).
fs::path make_sample_tree(const fs::path& base) {
  const fs::path root = base / "sequence";
  std::string all_bytes;
  for (int i = 0; i < 256; ++i) all_bytes.push_back(static_cast<char>(i));
  std::string big;  // several 64 KiB chunks, not a multiple of 512
  for (int i = 0; i < 200'003; ++i) big.push_back(static_cast<char>((i * 7919) >> 3));
  write_bytes(root / "mav0/cam0/data/1403636579763555584.png", big);
  write_bytes(root / "mav0/cam0/data.csv", "#timestamp [ns],filename\n1403636579763555584,1403636579763555584.png\n");
  write_bytes(root / "mav0/imu0/all_bytes.bin", all_bytes);
  write_bytes(root / "mav0/empty.txt", "");
  fs::create_directories(root / "mav0/empty_dir");
  // > 100 characters, split into ustar prefix + name.
  write_bytes(root / ("mav0/cam1/" + std::string(80, 'x') + "/" + std::string(40, 'y') + ".txt"), "prefix split");
  // > 100 characters with a last component too long for the name field: GNU 'L'.
  write_bytes(root / ("mav0/" + std::string(120, 'z') + ".txt"), "long last component");
  // > 255 characters: GNU 'L'.
  const std::string deep = "mav0/" + std::string(60, 'a') + "/" + std::string(60, 'b') + "/" + std::string(60, 'c') +
                           "/" + std::string(60, 'd') + "/file_with_a_long_path.bin";
  EXPECT_GT(deep.size(), 255u);
  write_bytes(root / deep, all_bytes + big);
  return root;
}

fs::path write_tar_file(const fs::path& root, const fs::path& tar) {
  std::ofstream out(tar, std::ios::binary);
  write_directory_tar(root,
                      [&](const char* data, std::size_t size) { out.write(data, static_cast<std::streamsize>(size)); });
  return tar;
}

// Hand-made headers, for entries our writer refuses to produce.
std::string raw_header(const std::string& name, char type, std::uint64_t size, const std::string& linkname = "",
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

std::string raw_entry(const std::string& name, char type, const std::string& data, const std::string& linkname = "") {
  return raw_header(name, type, data.size(), linkname) + data + std::string((512 - data.size() % 512) % 512, '\0');
}

const std::string kEnd(1024, '\0');

std::string error_of(const fs::path& tar, const fs::path& destination, const TarLimits& limits = {}) {
  try {
    extract_tar(tar, destination, limits);
  } catch (const DataError& e) {
    return e.what();
  }
  return "<no DataError>";
}

#define EXPECT_CONTAINS(text, word) EXPECT_NE(std::string(text).find(word), std::string::npos) << (text)

TEST(TarRoundTrip, NestedTreeIsByteIdentical) {
  TempDir tmp;
  const fs::path root = make_sample_tree(tmp.path());
  fs::create_directory_symlink(root / "mav0", root / "link_to_mav0");  // skipped by the writer
  fs::create_symlink(root / "mav0/empty.txt", root / "mav0/link.txt");
  const fs::path tar = tmp.path() / "out.tar";
  std::uint64_t last_done = 0, last_total = 0;
  bool monotonic = true;
  {
    std::ofstream out(tar, std::ios::binary);
    write_directory_tar(
        root, [&](const char* d, std::size_t n) { out.write(d, static_cast<std::streamsize>(n)); },
        [&](std::uint64_t done, std::uint64_t total) {
          monotonic = monotonic && done >= last_done;
          last_done = done;
          last_total = total;
        });
  }
  const std::uint64_t size = fs::file_size(tar);
  EXPECT_EQ(directory_tar_size(root), size);
  EXPECT_EQ(size % 512, 0u);
  EXPECT_TRUE(monotonic);
  EXPECT_EQ(last_done, size);
  EXPECT_EQ(last_total, size);

  const fs::path dest = tmp.path() / "extracted" / "nested";  // created by extract_tar
  std::uint64_t read_done = 0, read_total = 0;
  const TarExtractReport report = extract_tar(tar, dest, {}, [&](std::uint64_t done, std::uint64_t total) {
    read_done = done;
    read_total = total;
  });
  EXPECT_EQ(read_total, size);
  EXPECT_EQ(read_done, size);
  fs::remove(root / "link_to_mav0");
  fs::remove(root / "mav0/link.txt");
  expect_same_tree(root, dest);
  EXPECT_EQ(report.files, 7u);
  EXPECT_EQ(report.directories, read_tree(root).directories.size());
  EXPECT_EQ(report.skipped, 0u);
  std::uint64_t bytes = 0;
  for (const auto& [path, content] : read_tree(root).files) bytes += content.size();
  EXPECT_EQ(report.bytes, bytes);
  EXPECT_FALSE(fs::exists(dest / "link_to_mav0"));
}

TEST(TarWriter, HeaderLayoutAndFinish) {
  TempDir tmp;
  std::string archive;
  TarWriter writer([&](const char* d, std::size_t n) { archive.append(d, n); });
  write_bytes(tmp.path() / "f.bin", "hello");
  const std::string split = std::string(120, 'p') + "/" + std::string(90, 'n');  // ustar prefix + name
  const std::string long_path = std::string(300, 'g');                           // no usable '/': a pax record
  writer.add_file(split, tmp.path() / "f.bin");
  EXPECT_EQ(archive.size(), 1024u);  // header + one data block, no extended header
  EXPECT_EQ(tar_entry_bytes(split, 5), 1024u);
  EXPECT_EQ(archive.compare(345, 120, std::string(120, 'p')), 0);  // ustar prefix field
  EXPECT_EQ(archive.compare(257, 6, std::string("ustar", 6)), 0);  // POSIX magic
  writer.add_file(long_path, tmp.path() / "f.bin");
  EXPECT_EQ(archive.size(), 1024u + tar_entry_bytes(long_path, 5));
  EXPECT_EQ(archive[1024 + 156], 'x');  // pax extended header
  EXPECT_NE(archive.find("path=" + long_path + "\n"), std::string::npos);
  writer.add_directory_entry("dir");
  EXPECT_EQ(archive.compare(archive.size() - 512, 4, "dir/"), 0);
  EXPECT_EQ(archive[archive.size() - 512 + 156], '5');
  const std::uint64_t before_end = writer.bytes_written();
  writer.finish();
  writer.finish();  // idempotent
  EXPECT_EQ(writer.bytes_written(), before_end + 1024);
  EXPECT_EQ(archive.size(), writer.bytes_written());
  EXPECT_THROW(writer.add_directory_entry("late"), Error);

  TarWriter other([](const char*, std::size_t) {});
  EXPECT_THROW(other.add_file("missing", tmp.path() / "does_not_exist"), Error);
  EXPECT_THROW(other.add_file("dir", tmp.path()), Error);
  EXPECT_THROW(other.add_file("../up", tmp.path() / "f.bin"), Error);
  EXPECT_THROW(write_directory_tar(tmp.path() / "f.bin", [](const char*, std::size_t) {}), Error);

  // A sink that fails (a closed connection) is an Error of the writer, not a crash.
  TarWriter broken([](const char*, std::size_t) { throw Error("the connection closed"); });
  try {
    broken.add_file("f.bin", tmp.path() / "f.bin");
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_CONTAINS(e.what(), "the connection closed");
  }
}

// Files of 8 GiB and more get their size in a pax record (ustar's field holds
// less); the measured size is exact without reading any data.
TEST(TarWriter, EntrySizesAreExactForHugeFiles) {
  const std::uint64_t huge = (9ull << 30) + 7;
  EXPECT_EQ(tar_entry_bytes("mav0/huge.bin", huge) % 512, 0u);
  EXPECT_GT(tar_entry_bytes("mav0/huge.bin", huge), 512 + huge + 511);  // a pax header in front
  EXPECT_EQ(tar_entry_bytes("mav0/small.bin", 1000), 512u + 1024u);
  EXPECT_EQ(tar_entry_bytes("mav0/", 0), 512u);
}

bool have_gnu_tar() { return fs::exists("/usr/bin/tar"); }

std::string quoted(const fs::path& p) {
  std::string q(1, '\'');
  q += p.string();
  q += '\'';
  return q;
}

TEST(TarInterop, ExtractsArchivesMadeByGnuTar) {
  if (!have_gnu_tar()) ORBATLAS_NEEDS("/usr/bin/tar (GNU tar interoperability is not tested)");
  TempDir tmp;
  const fs::path root = make_sample_tree(tmp.path());
  for (const std::string format : {"gnu", "pax"}) {
    SCOPED_TRACE(format);
    const fs::path tar = tmp.path() / (format + ".tar"), dest = tmp.path() / ("out_" + format);
    // "-C root ." gives "./mav0/..." entry names.
    const std::string command =
        "/usr/bin/tar --format=" + format + " -cf " + quoted(tar) + " -C " + quoted(root) + " .";
    ASSERT_EQ(std::system(command.c_str()), 0) << command;
    const TarExtractReport report = extract_tar(tar, dest);
    expect_same_tree(root, dest);
    EXPECT_EQ(report.files, 7u);
    EXPECT_EQ(report.skipped, 0u);
  }
}

TEST(TarInterop, GnuTarExtractsOurArchives) {
  if (!have_gnu_tar()) ORBATLAS_NEEDS("/usr/bin/tar (GNU tar interoperability is not tested)");
  TempDir tmp;
  const fs::path root = make_sample_tree(tmp.path());
  const fs::path tar = write_tar_file(root, tmp.path() / "ours.tar"), dest = tmp.path() / "out";
  fs::create_directories(dest);
  const fs::path listing = tmp.path() / "listing.txt";
  const std::string list = "/usr/bin/tar -tf " + quoted(tar) + " > " + quoted(listing);
  ASSERT_EQ(std::system(list.c_str()), 0) << list;
  EXPECT_CONTAINS(read_bytes(listing), "/file_with_a_long_path.bin\n");
  EXPECT_CONTAINS(read_bytes(listing), "mav0/cam0/data/1403636579763555584.png\n");
  const std::string extract = "/usr/bin/tar -xf " + quoted(tar) + " -C " + quoted(dest);
  ASSERT_EQ(std::system(extract.c_str()), 0) << extract;
  expect_same_tree(root, dest);
}

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

// GNU and pax sparse files (refused by the hand-written reader) are extracted
// with their holes, and count at their full size against the limits.
TEST(TarInterop, SparseFilesFromGnuTar) {
  if (!have_gnu_tar()) ORBATLAS_NEEDS("/usr/bin/tar (sparse archives are not tested)");
  TempDir tmp;
  const fs::path root = tmp.path() / "root";
  fs::create_directories(root);
  {
    std::ofstream out(root / "sparse.bin", std::ios::binary);
    out << "head";
    out.seekp(3 << 20);
    out << "middle";
    out.seekp(7 << 20);
    out << "tail";
  }
  const std::string expected = read_bytes(root / "sparse.bin");
  for (const std::string format : {"gnu", "pax"}) {
    SCOPED_TRACE(format);
    const fs::path tar = tmp.path() / (format + ".tar"), dest = tmp.path() / ("out_" + format);
    const std::string command =
        "/usr/bin/tar --sparse --format=" + format + " -cf " + quoted(tar) + " -C " + quoted(root) + " sparse.bin";
    ASSERT_EQ(std::system(command.c_str()), 0) << command;
    EXPECT_LT(fs::file_size(tar), 100'000u);  // the holes are not in the archive
    const TarExtractReport report = extract_tar(tar, dest);
    EXPECT_EQ(report.files, 1u);
    EXPECT_EQ(report.bytes, expected.size());
    EXPECT_TRUE(read_bytes(dest / "sparse.bin") == expected);
    TarLimits limits;
    limits.max_total_bytes = 1 << 20;  // a small archive, but 7 MB of file
    EXPECT_CONTAINS(error_of(tar, tmp.path() / ("limited_" + format), limits), "max_total_bytes");
  }
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

// The upload path: chunks of any size pushed while the archive "arrives", no copy
// of the archive anywhere, the same tree as the file extractor's.
TEST(TarStream, ExtractsWhileTheArchiveArrives) {
  TempDir tmp;
  const fs::path root = make_sample_tree(tmp.path());
  std::string archive;
  write_directory_tar(root, [&](const char* d, std::size_t n) { archive.append(d, n); });
  archive += std::string(10240 - archive.size() % 10240, '\0');  // record padding, as GNU tar writes it
  const fs::path dest = tmp.path() / "streamed";
  fs::create_directories(dest);
  TarStreamExtractor extractor(dest, {}, "the upload", 2);
  for (std::size_t at = 0, step = 1; at < archive.size(); at += step, step = step * 3 % 70'001 + 1)
    ASSERT_TRUE(extractor.write(archive.data() + at, std::min(step, archive.size() - at))) << "at byte " << at;
  const TarExtractReport report = extractor.finish();
  EXPECT_EQ(extractor.state(), TarStreamExtractor::State::kSucceeded);
  EXPECT_EQ(report.files, 7u);
  expect_same_tree(root, dest);
}

TEST(TarStream, ABadArchiveStopsTheSenderAndSaysWhy) {
  TempDir tmp;
  const fs::path dest = tmp.path() / "bad";
  fs::create_directories(dest);
  TarStreamExtractor extractor(dest, {}, "the upload", 2);
  const std::string evil = raw_entry("../evil", '0', "evil") + std::string(1 << 20, 'x');
  bool refused = false;
  for (std::size_t at = 0; at < evil.size() && !refused; at += 4096) refused = !extractor.write(evil.data() + at, 4096);
  EXPECT_TRUE(refused) << "the sender was never told to stop";
  EXPECT_EQ(extractor.state(), TarStreamExtractor::State::kFailed);
  try {
    extractor.finish();
    ADD_FAILURE() << "no error";
  } catch (const DataError& e) {
    EXPECT_CONTAINS(e.what(), "'..'");
    EXPECT_CONTAINS(e.what(), "the upload");
  }
  EXPECT_FALSE(fs::exists(tmp.path() / "evil"));
}

TEST(TarStream, ACutShortUploadIsCancelledWithoutWaiting) {
  TempDir tmp;
  const fs::path dest = tmp.path() / "cut";
  fs::create_directories(dest);
  const std::string archive = raw_entry("a.bin", '0', std::string(100'000, 'a')) + kEnd;
  {
    TarStreamExtractor extractor(dest, {}, "the upload", 2);
    ASSERT_TRUE(extractor.write(archive.data(), 30'000));
    extractor.cancel();  // the client went away
    EXPECT_FALSE(extractor.write(archive.data() + 30'000, 1000));
    EXPECT_THROW(extractor.finish(), Error);
  }
  TarStreamExtractor empty(tmp.path() / "empty", {}, "the upload");
  EXPECT_THROW(empty.finish(), DataError);  // no bytes: not a tar archive
}

}  // namespace
}  // namespace orbatlas
