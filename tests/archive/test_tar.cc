// Tar archives: a directory written and extracted byte for byte, the
// writer's headers, archives exchanged with GNU tar (sparse files included),
// and extraction while an upload arrives. What extraction refuses is in
// test_tar_errors.cc.
#include <gtest/gtest.h>

#include <cstdint>
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
#include "tests/support/tar_test_files.h"

namespace orbatlas {
namespace {

namespace fs = std::filesystem;
using test::error_of;
using test::kEnd;
using test::raw_entry;
using test::read_bytes;
using test::TempDir;
using test::write_bytes;

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
