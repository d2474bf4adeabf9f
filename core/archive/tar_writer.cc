#include "core/archive/tar_writer.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cstring>
#include <fstream>
#include <system_error>
#include <vector>

#include "core/common/error.h"

namespace orbatlas {
namespace {

// A tar archive is a sequence of 512-byte blocks: a header block per entry, then the
// entry's data padded with zeros to a whole block; two zero blocks end the archive.
constexpr std::size_t kBlock = 512;
constexpr std::size_t kChunk = 64 * 1024;

// ustar header fields: offset and length of each within the header block.
struct Field {
  std::size_t offset, length;
};
constexpr Field kName{0, 100}, kMode{100, 8}, kUid{108, 8}, kGid{116, 8}, kSize{124, 12}, kMtime{136, 12},
    kChecksum{148, 8}, kTypeflag{156, 1}, kMagic{257, 6}, kVersion{263, 2}, kPrefix{345, 155};

using Header = std::array<char, kBlock>;

std::uint64_t padded(std::uint64_t size) { return (size + kBlock - 1) / kBlock * kBlock; }

// Where a path goes in the header. ustar stores up to 100 bytes in `name` and,
// when the path is longer, up to 155 more in `prefix`: the reader joins them as
// prefix + "/" + name, so the split must fall on a '/'. Longer paths (or ones with
// no usable '/') need a GNU 'L' entry whose data is the full name.
struct NameLayout {
  std::string prefix, name;
  bool long_name_entry = false;
};

NameLayout layout_name(const std::string& path) {
  if (path.size() <= kName.length) return {"", path, false};
  // The longest usable prefix gives the shortest name. A '/' at the very end (a
  // directory's) would leave an empty name, so it is not a split point.
  const std::size_t pos = path.rfind('/', std::min(path.size() - 2, kPrefix.length));
  if (pos != std::string::npos && pos > 0 && path.size() - pos - 1 <= kName.length)
    return {path.substr(0, pos), path.substr(pos + 1), false};
  return {"", path.substr(0, kName.length), true};
}

// Numbers are octal text, NUL-terminated. Values too large for the field (a file of
// 8 GiB or more in the 12-byte size field) use GNU base-256: the first byte is 0x80
// and the value follows big-endian.
void put_number(Header& h, Field f, std::uint64_t value) {
  const std::size_t digits = f.length - 1;
  if (digits * 3 >= 64 || value < (std::uint64_t{1} << (3 * digits))) {
    for (std::size_t i = digits; i-- > 0; value >>= 3) h[f.offset + i] = static_cast<char>('0' + (value & 7));
    h[f.offset + digits] = '\0';
    return;
  }
  for (std::size_t i = f.length; i-- > 1; value >>= 8) h[f.offset + i] = static_cast<char>(value & 0xff);
  h[f.offset] = static_cast<char>(0x80);
}

void put_text(Header& h, Field f, const std::string& text) {
  std::memcpy(h.data() + f.offset, text.data(), std::min(text.size(), f.length));
}

void check_archive_path(const std::string& path) {
  ORBATLAS_CHECK(!path.empty(), "tar: empty archive path");
  ORBATLAS_CHECK(path.front() != '/', "tar: absolute archive path '" << path << "'");
  ORBATLAS_CHECK(path.find('\0') == std::string::npos, "tar: NUL byte in archive path '" << path << "'");
  std::size_t start = 0;
  while (start <= path.size()) {
    const std::size_t end = std::min(path.find('/', start), path.size());
    ORBATLAS_CHECK(path.compare(start, end - start, "..") != 0, "tar: '..' in archive path '" << path << "'");
    start = end + 1;
  }
}

std::string directory_path(std::string path) {
  while (!path.empty() && path.back() == '/') path.pop_back();
  return path + "/";
}

std::int64_t mtime_seconds(const std::filesystem::path& path) {
  std::error_code ec;
  const auto t = std::filesystem::last_write_time(path, ec);
  if (ec) return 0;
  const auto sys = std::chrono::file_clock::to_sys(t);
  return std::chrono::duration_cast<std::chrono::seconds>(sys.time_since_epoch()).count();
}

// The entries of a folder tree, in the order and with the sizes they are archived.
struct TreeEntry {
  std::filesystem::path relative, source;
  bool directory = false;
  std::uint64_t size = 0;
};

std::vector<TreeEntry> list_tree(const std::filesystem::path& root) {
  std::error_code ec;
  ORBATLAS_CHECK(std::filesystem::is_directory(root, ec), "tar: not a directory: " << root);
  std::vector<TreeEntry> entries;
  std::filesystem::recursive_directory_iterator it(root, ec), end;  // does not follow directory symlinks
  ORBATLAS_CHECK(!ec, "tar: cannot list " << root << ": " << ec.message());
  for (; it != end; it.increment(ec)) {
    ORBATLAS_CHECK(!ec, "tar: cannot list " << root << ": " << ec.message());
    const auto status = it->symlink_status(ec);
    ORBATLAS_CHECK(!ec, "tar: cannot stat " << it->path() << ": " << ec.message());
    TreeEntry e{it->path().lexically_relative(root), it->path(), false, 0};
    if (std::filesystem::is_directory(status)) {
      e.directory = true;
    } else if (std::filesystem::is_regular_file(status)) {
      e.size = it->file_size(ec);
      ORBATLAS_CHECK(!ec, "tar: cannot stat " << it->path() << ": " << ec.message());
    } else {
      continue;  // symlinks, sockets, fifos, devices
    }
    entries.push_back(std::move(e));
  }
  ORBATLAS_CHECK(!ec, "tar: cannot list " << root << ": " << ec.message());
  // path comparison is component-wise, so a directory comes right before its content.
  std::sort(entries.begin(), entries.end(),
            [](const TreeEntry& a, const TreeEntry& b) { return a.relative < b.relative; });
  return entries;
}

std::uint64_t tree_tar_size(const std::vector<TreeEntry>& entries) {
  std::uint64_t total = 2 * kBlock;
  for (const auto& e : entries)
    total += e.directory ? tar_entry_bytes(directory_path(e.relative.generic_string()), 0)
                         : tar_entry_bytes(e.relative.generic_string(), e.size);
  return total;
}

}  // namespace

TarWriter::TarWriter(TarSink sink) : sink_(std::move(sink)) {
  ORBATLAS_CHECK(static_cast<bool>(sink_), "TarWriter: no sink");
}

void TarWriter::emit(const char* data, std::size_t size) {
  sink_(data, size);
  bytes_written_ += size;
}

void TarWriter::pad_to_block(std::uint64_t data_size) {
  static constexpr std::array<char, kBlock> zeros{};
  const std::size_t rest = static_cast<std::size_t>(padded(data_size) - data_size);
  if (rest > 0) emit(zeros.data(), rest);
}

void TarWriter::write_header(const std::string& archive_path, char typeflag, std::uint32_t mode, std::uint64_t size,
                             std::int64_t mtime) {
  ORBATLAS_CHECK(!finished_, "TarWriter: entry '" << archive_path << "' added after finish()");
  const NameLayout layout = layout_name(archive_path);
  if (layout.long_name_entry) {
    // GNU long name: a pseudo-entry named "././@LongLink" whose data is the full
    // path plus a terminating NUL; the real header that follows has it truncated.
    const std::string data = archive_path + '\0';
    write_header("././@LongLink", 'L', 0, data.size(), 0);
    emit(data.data(), data.size());
    pad_to_block(data.size());
  }
  Header h{};
  put_text(h, kName, layout.name);
  put_text(h, kPrefix, layout.prefix);
  put_number(h, kMode, mode);
  put_number(h, kUid, 0);
  put_number(h, kGid, 0);
  put_number(h, kSize, size);
  put_number(h, kMtime, static_cast<std::uint64_t>(std::max<std::int64_t>(mtime, 0)));
  h[kTypeflag.offset] = typeflag;
  put_text(h, kMagic, std::string("ustar", 6));  // "ustar\0" then version "00": POSIX ustar
  put_text(h, kVersion, "00");
  // The checksum is the sum of the header's bytes (unsigned) with the checksum field
  // itself counted as 8 spaces; stored as 6 octal digits, NUL, space.
  std::memset(h.data() + kChecksum.offset, ' ', kChecksum.length);
  unsigned sum = 0;
  for (char c : h) sum += static_cast<unsigned char>(c);
  put_number(h, Field{kChecksum.offset, 7}, sum);
  emit(h.data(), h.size());
}

void TarWriter::add_file(const std::string& archive_path, const std::filesystem::path& source) {
  check_archive_path(archive_path);
  std::error_code ec;
  ORBATLAS_CHECK(std::filesystem::is_regular_file(source, ec), "tar: not a readable regular file: " << source);
  const std::uint64_t size = std::filesystem::file_size(source, ec);
  ORBATLAS_CHECK(!ec, "tar: cannot stat " << source << ": " << ec.message());
  std::ifstream in(source, std::ios::binary);
  ORBATLAS_CHECK(in, "tar: cannot open " << source);
  write_header(archive_path, '0', 0644, size, mtime_seconds(source));
  // Exactly `size` bytes follow the header, whatever happens to the file meanwhile.
  std::vector<char> buffer(kChunk);
  for (std::uint64_t left = size; left > 0;) {
    const auto want = static_cast<std::streamsize>(std::min<std::uint64_t>(left, kChunk));
    in.read(buffer.data(), want);
    ORBATLAS_CHECK(in.gcount() == want, "tar: cannot read " << source << " (read error, or it shrank while archived)");
    emit(buffer.data(), static_cast<std::size_t>(want));
    left -= static_cast<std::uint64_t>(want);
  }
  pad_to_block(size);
}

void TarWriter::add_directory_entry(const std::string& archive_path, std::int64_t mtime) {
  const std::string path = directory_path(archive_path);
  check_archive_path(path);
  write_header(path, '5', 0755, 0, mtime);
}

void TarWriter::finish() {
  if (finished_) return;
  static constexpr std::array<char, 2 * kBlock> zeros{};
  emit(zeros.data(), zeros.size());
  finished_ = true;
}

std::uint64_t tar_entry_bytes(const std::string& archive_path, std::uint64_t data_size) {
  const std::uint64_t long_name =
      layout_name(archive_path).long_name_entry ? kBlock + padded(archive_path.size() + 1) : 0;
  return long_name + kBlock + padded(data_size);
}

void write_directory_tar(const std::filesystem::path& root, const TarSink& sink, const TarProgress& progress) {
  const auto entries = list_tree(root);
  const std::uint64_t total = tree_tar_size(entries);
  std::uint64_t done = 0;
  TarWriter writer([&](const char* data, std::size_t size) {
    sink(data, size);
    done += size;
    if (progress) progress(done, total);
  });
  for (const auto& e : entries) {
    if (e.directory)
      writer.add_directory_entry(e.relative.generic_string(), mtime_seconds(e.source));
    else
      writer.add_file(e.relative.generic_string(), e.source);
  }
  writer.finish();
  ORBATLAS_CHECK(writer.bytes_written() == total, "tar: " << root << " changed while it was archived ("
                                                          << writer.bytes_written() << " bytes written, " << total
                                                          << " announced)");
}

std::uint64_t directory_tar_size(const std::filesystem::path& root) { return tree_tar_size(list_tree(root)); }

}  // namespace orbatlas
