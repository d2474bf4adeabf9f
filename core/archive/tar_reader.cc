#include "core/archive/tar_reader.h"

#include <algorithm>
#include <array>
#include <cstring>
#include <fstream>
#include <optional>
#include <string_view>
#include <system_error>
#include <vector>

#include "core/common/error.h"

namespace orbatlas {
namespace {

namespace fs = std::filesystem;
using ProgressFn = std::function<void(std::uint64_t, std::uint64_t)>;

// A tar archive is a sequence of 512-byte blocks: a header block per entry, then the
// entry's data padded with zeros to a whole block. A zero block ends the archive
// (writers put two; one is accepted, none means the archive was cut short).
constexpr std::size_t kBlock = 512;
constexpr std::size_t kChunk = 64 * 1024;
constexpr std::uint64_t kMaxMetadataBytes = 1 << 20;  // GNU long names and pax records

struct Field {
  std::size_t offset, length;
};
constexpr Field kName{0, 100}, kSize{124, 12}, kChecksum{148, 8}, kTypeflag{156, 1}, kMagic{257, 6}, kPrefix{345, 155};

using Block = std::array<char, kBlock>;

std::uint64_t padded(std::uint64_t size) { return (size + kBlock - 1) / kBlock * kBlock; }

std::string text_field(const Block& h, Field f) {
  const char* p = h.data() + f.offset;
  return std::string(p, std::find(p, p + f.length, '\0'));
}

// Numeric fields are octal text (optionally space-padded, ended by NUL or space),
// or GNU base-256 for values too large for the digits: first byte 0x80 (0xff marks
// a negative number), value big-endian in the remaining bits.
std::optional<std::uint64_t> number_field(const Block& h, Field f) {
  const auto* p = reinterpret_cast<const unsigned char*>(h.data() + f.offset);
  if (p[0] & 0x80) {
    if (p[0] & 0x40) return std::nullopt;  // negative
    std::uint64_t v = p[0] & 0x3f;
    for (std::size_t i = 1; i < f.length; ++i) {
      if (v >> 56) return std::nullopt;
      v = (v << 8) | p[i];
    }
    return v;
  }
  std::size_t i = 0;
  while (i < f.length && p[i] == ' ') ++i;
  std::uint64_t v = 0;
  for (; i < f.length && p[i] >= '0' && p[i] <= '7'; ++i) {
    if (v >> 61) return std::nullopt;
    v = (v << 3) | (p[i] - '0');
  }
  if (i < f.length && p[i] != ' ' && p[i] != '\0') return std::nullopt;
  return v;
}

// The checksum is the sum of the header bytes with the checksum field counted as
// spaces. Historic writers summed signed chars, so both sums are accepted.
bool checksum_ok(const Block& h) {
  const auto stored = number_field(h, kChecksum);
  if (!stored || h[kChecksum.offset] == '\0') return false;
  std::uint64_t unsigned_sum = 0;
  std::int64_t signed_sum = 0;
  for (std::size_t i = 0; i < kBlock; ++i) {
    const bool in_field = i >= kChecksum.offset && i < kChecksum.offset + kChecksum.length;
    const char c = in_field ? ' ' : h[i];
    unsigned_sum += static_cast<unsigned char>(c);
    signed_sum += static_cast<signed char>(c);
  }
  return *stored == unsigned_sum || static_cast<std::int64_t>(*stored) == signed_sum;
}

bool all_zero(const Block& h) {
  return std::all_of(h.begin(), h.end(), [](char c) { return c == '\0'; });
}

// The archive file, read block by block, with the offset for messages and progress.
class ArchiveInput {
 public:
  ArchiveInput(const fs::path& path, const ProgressFn& progress)
      : path_(path), in_(path, std::ios::binary), progress_(progress) {
    std::error_code ec;
    size_ = fs::file_size(path, ec);
    if (ec || !in_) throw DataError("tar: cannot open archive " + path.string());
  }
  std::uint64_t offset() const { return offset_; }
  std::uint64_t remaining() const { return size_ > offset_ ? size_ - offset_ : 0; }
  // Whether `size` bytes of data and their padding are still in the file.
  bool holds(std::uint64_t size) const { return size <= remaining() && padded(size) <= remaining(); }

  // At the end-of-archive marker: whatever follows it is ignored, so all is done.
  void finish() {
    if (progress_) progress_(size_, size_);
  }

  // One block; false at the end of the file (nothing left to read).
  bool read_block(Block& b) {
    if (remaining() == 0) return false;
    read_exact(b.data(), kBlock);
    return true;
  }

  // An entry's data followed by its padding; data goes to out in chunks.
  void read_data(std::uint64_t size, const std::function<void(const char*, std::size_t)>& out) {
    std::vector<char> buffer(kChunk);
    for (std::uint64_t left = padded(size); left > 0;) {
      const auto n = static_cast<std::size_t>(std::min<std::uint64_t>(left, kChunk));
      read_exact(buffer.data(), n);
      const std::uint64_t used = padded(size) - left;  // data bytes before this chunk
      if (used < size) out(buffer.data(), static_cast<std::size_t>(std::min<std::uint64_t>(n, size - used)));
      left -= n;
    }
  }

 private:
  void read_exact(char* dst, std::size_t n) {
    in_.read(dst, static_cast<std::streamsize>(n));
    if (in_.gcount() != static_cast<std::streamsize>(n))
      throw DataError("tar: " + path_.string() + ": truncated archive (ends at byte " +
                      std::to_string(offset_ + static_cast<std::uint64_t>(in_.gcount())) + " inside a block)");
    offset_ += n;
    if (progress_) progress_(offset_, size_);
  }

  fs::path path_;
  std::ifstream in_;
  ProgressFn progress_;
  std::uint64_t size_ = 0, offset_ = 0;
};

// Metadata that applies to the next real entry: a GNU long name ('L') or pax
// extended header ('x') records. The pax path wins over the GNU name.
struct Pending {
  std::optional<std::string> gnu_name, pax_path;
  std::optional<std::uint64_t> pax_size;
};

std::optional<std::uint64_t> decimal(std::string_view text) {
  if (text.empty()) return std::nullopt;
  std::uint64_t v = 0;
  for (char c : text) {
    if (c < '0' || c > '9' || v > (UINT64_MAX - 9) / 10) return std::nullopt;
    v = v * 10 + static_cast<std::uint64_t>(c - '0');
  }
  return v;
}

// pax records are "<length> <key>=<value>\n", the decimal length counting the whole
// record including itself. Only "path" (and "size", which moves the data) matter.
void parse_pax(std::string_view data, Pending& pending, const std::string& where) {
  while (!data.empty() && data.front() != '\0') {
    const std::size_t space = data.find(' ');
    const auto length = space == std::string_view::npos ? std::nullopt : decimal(data.substr(0, space));
    if (!length || *length < space + 2 || *length > data.size() || data[*length - 1] != '\n')
      throw DataError(where + ": malformed pax extended header");
    const std::string_view record = data.substr(space + 1, *length - space - 2);
    const std::size_t eq = record.find('=');
    if (eq == std::string_view::npos) throw DataError(where + ": malformed pax record '" + std::string(record) + "'");
    const std::string_view key = record.substr(0, eq), value = record.substr(eq + 1);
    if (key == "path") pending.pax_path = std::string(value);
    if (key == "size") {  // written for files of 8 GiB or more
      pending.pax_size = decimal(value);
      if (!pending.pax_size) throw DataError(where + ": bad pax size '" + std::string(value) + "'");
    }
    data.remove_prefix(*length);
  }
}

// Drops empty and "." components ("./a//b" -> "a/b"); refuses absolute paths and
// ".." components, the two ways an entry could land outside the destination.
std::vector<std::string> safe_components(const std::string& name, const std::string& where) {
  if (!name.empty() && name.front() == '/') throw DataError(where + ": absolute path refused");
  std::vector<std::string> parts;
  std::size_t start = 0;
  while (start <= name.size()) {
    const std::size_t end = std::min(name.find('/', start), name.size());
    const std::string part = name.substr(start, end - start);
    if (part == "..") throw DataError(where + ": '..' path component refused");
    if (part.find('\0') != std::string::npos) throw DataError(where + ": NUL byte in path");
    if (!part.empty() && part != ".") parts.push_back(part);
    start = end + 1;
  }
  return parts;
}

// Creates destination/parts[0]/.../parts[count-1], refusing to go through a symlink
// already present in the destination (it could point anywhere).
fs::path make_directories(const fs::path& destination, const std::vector<std::string>& parts, std::size_t count,
                          const std::string& where) {
  fs::path p = destination;
  for (std::size_t i = 0; i < count; ++i) {
    p /= parts[i];
    std::error_code ec;
    const auto status = fs::symlink_status(p, ec);
    if (fs::is_symlink(status)) throw DataError(where + ": refusing to write through the symlink " + p.string());
    if (!fs::exists(status)) {
      fs::create_directory(p, ec);
      if (ec) throw Error("tar: cannot create directory " + p.string() + ": " + ec.message());
    } else if (!fs::is_directory(status)) {
      throw DataError(where + ": " + p.string() + " exists and is not a directory");
    }
  }
  return p;
}

const char* skipped_kind(char type) {
  switch (type) {
    case '1':
      return "hard link";
    case '2':
      return "symlink";
    case '3':
      return "character device";
    case '4':
      return "block device";
    case '6':
      return "fifo";
    default:
      return nullptr;
  }
}

// The path in a header block. POSIX ustar (magic "ustar\0") keeps a long path's
// leading part in `prefix`; the GNU format (magic "ustar  ") uses those bytes for
// other things, so they are ignored there.
std::string header_path(const Block& h) {
  std::string name = text_field(h, kName);
  if (std::memcmp(h.data() + kMagic.offset, "ustar", kMagic.length) == 0 && h[kPrefix.offset] != '\0')
    name = text_field(h, kPrefix) + "/" + name;
  return name;
}

// Checks the header's checksum; a bad first header means the file is no tar at all.
void check_header(const Block& h, std::uint64_t offset, std::uint64_t entries, const std::string& file) {
  if (checksum_ok(h)) return;
  if (offset == 0) {
    const bool gzip = static_cast<unsigned char>(h[0]) == 0x1f && static_cast<unsigned char>(h[1]) == 0x8b;
    throw DataError(file + ": not a tar archive (bad header checksum at the start" +
                    (gzip ? "; the file is gzip-compressed, send the uncompressed .tar)" : ")"));
  }
  throw DataError(file + ": bad header checksum at byte " + std::to_string(offset) + " (after " +
                  std::to_string(entries) + " entries; corrupted or not a tar archive)");
}

void check_limits(std::uint64_t size, const TarExtractReport& report, const TarLimits& limits,
                  const std::string& entry) {
  if (size > limits.max_file_bytes)
    throw DataError(entry + ": " + std::to_string(size) + " bytes, over the max_file_bytes limit of " +
                    std::to_string(limits.max_file_bytes));
  if (size > limits.max_total_bytes - std::min(report.bytes, limits.max_total_bytes))
    throw DataError(entry + ": extracted size would exceed the max_total_bytes limit of " +
                    std::to_string(limits.max_total_bytes));
}

void write_file(ArchiveInput& in, std::uint64_t size, const fs::path& target, const std::string& entry) {
  std::error_code ec;
  const auto status = fs::symlink_status(target, ec);
  if (fs::is_symlink(status) || fs::is_directory(status))
    throw DataError(entry + ": " + target.string() + " already exists as a " +
                    (fs::is_symlink(status) ? "symlink" : "directory"));
  fs::remove(target, ec);  // a later duplicate replaces the file (and never writes into a hard link)
  std::ofstream out(target, std::ios::binary | std::ios::trunc);
  if (!out) throw Error("tar: cannot create " + target.string());
  in.read_data(size, [&](const char* p, std::size_t n) { out.write(p, static_cast<std::streamsize>(n)); });
  out.close();
  if (!out) throw Error("tar: cannot write " + target.string());
}

}  // namespace

TarExtractReport extract_tar(const fs::path& archive, const fs::path& destination, const TarLimits& limits,
                             const std::function<void(std::uint64_t, std::uint64_t)>& progress) {
  ArchiveInput in(archive, progress);
  std::error_code ec;
  fs::create_directories(destination, ec);
  if (ec) throw Error("tar: cannot create " + destination.string() + ": " + ec.message());
  const std::string file = "tar: " + archive.string();
  TarExtractReport report;
  Pending pending;
  std::uint64_t entries = 0;
  for (Block h;;) {
    const std::uint64_t header_offset = in.offset();
    if (header_offset == 0 && in.remaining() < kBlock)
      throw DataError(file + ": not a tar archive (" +
                      (in.remaining() == 0 ? std::string("empty file") : "shorter than one tar header") + ")");
    if (!in.read_block(h))
      throw DataError(file + ": truncated archive (no end-of-archive marker after " + std::to_string(entries) +
                      " entries)");
    if (all_zero(h)) {
      in.finish();
      break;
    }
    check_header(h, header_offset, entries, file);
    const char type = h[kTypeflag.offset];
    std::string name = header_path(h);
    const auto header_size = number_field(h, kSize);
    if (!header_size) throw DataError(file + ": entry '" + name + "': bad size field");
    std::uint64_t size = *header_size;

    if (type == 'L' || type == 'K' || type == 'x' || type == 'g') {  // metadata for the next entry
      const std::string where = file + ": entry '" + name + "'";
      if (size > kMaxMetadataBytes) throw DataError(where + ": metadata entry too large");
      if (!in.holds(size)) throw DataError(where + ": truncated archive (metadata cut short)");
      std::string data;
      in.read_data(size, [&](const char* p, std::size_t n) { data.append(p, n); });
      if (type == 'L') pending.gnu_name = data.substr(0, data.find('\0'));  // NUL-terminated
      if (type == 'x') parse_pax(data, pending, where);                     // 'K' (long link target) and 'g': unused
      continue;
    }
    if (pending.pax_path)
      name = *pending.pax_path;
    else if (pending.gnu_name)
      name = *pending.gnu_name;
    if (pending.pax_size) size = *pending.pax_size;
    pending = {};
    const std::string entry = file + ": entry '" + name + "'";
    if (++entries > limits.max_entries)
      throw DataError(entry + ": too many entries (limit " + std::to_string(limits.max_entries) + ")");
    if (type == 'S') throw DataError(entry + ": GNU sparse files are not supported (archive without --sparse)");

    const bool regular = type == '0' || type == '\0' || type == '7';  // '7': contiguous file, a regular file
    // Old writers mark directories only by a trailing '/' on a regular entry.
    const bool directory = type == '5' || (regular && !name.empty() && name.back() == '/');
    // Only regular files and unknown types carry data blocks; links, devices, fifos
    // and directories have none whatever their size field says.
    const bool has_data = !directory && !skipped_kind(type);
    if (has_data && !in.holds(size))
      throw DataError(entry + ": truncated archive (" + std::to_string(size) + " bytes of data, " +
                      std::to_string(in.remaining()) + " left in the file)");
    const auto parts = safe_components(name, entry);

    if (directory) {
      if (parts.empty()) continue;  // "./": the destination itself
      make_directories(destination, parts, parts.size(), entry);
      ++report.directories;
    } else if (regular) {
      if (parts.empty()) throw DataError(entry + ": empty file name");
      check_limits(size, report, limits, entry);
      const fs::path parent = make_directories(destination, parts, parts.size() - 1, entry);
      write_file(in, size, parent / parts.back(), entry);
      ++report.files;
      report.bytes += size;
    } else {  // links, devices, fifos, unknown types (e.g. a GNU volume label)
      ++report.skipped;
      const char* kind = skipped_kind(type);
      if (report.skipped_names.size() < TarExtractReport::kMaxSkippedNames)
        report.skipped_names.push_back(name + " (" + (kind ? kind : "type '" + std::string(1, type) + "'") + ")");
      if (has_data) in.read_data(size, [](const char*, std::size_t) {});
    }
  }
  return report;
}

}  // namespace orbatlas
