#include "core/archive/tar_reader.h"

#include <archive.h>
#include <archive_entry.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <exception>
#include <fstream>
#include <system_error>
#include <vector>

#include "core/common/error.h"

namespace orbatlas {
namespace {

namespace fs = std::filesystem;

constexpr std::size_t kChunk = 64 * 1024;
constexpr std::size_t kBlock = 512;

// libarchive pulls the archive through a C callback. Exceptions must not cross
// C frames: the callback keeps the source's exception and reports a read error,
// and the caller rethrows it.
struct SourceState {
  const TarSource* source = nullptr;
  std::vector<char> buffer = std::vector<char>(kChunk);
  std::uint64_t bytes = 0;
  bool ended = false;               // the source said there is no more
  unsigned char first[2] = {0, 0};  // the first two bytes, for the gzip hint
  std::exception_ptr error;
};

la_ssize_t read_callback(archive* a, void* client, const void** out) {
  auto* s = static_cast<SourceState*>(client);
  try {
    const std::size_t n = (*s->source)(s->buffer.data(), s->buffer.size());
    for (std::size_t i = 0; i < n && s->bytes + i < 2; ++i)
      s->first[s->bytes + i] = static_cast<unsigned char>(s->buffer[i]);
    s->bytes += n;
    s->ended = n == 0;
    *out = s->buffer.data();
    return static_cast<la_ssize_t>(n);
  } catch (...) {
    s->error = std::current_exception();
    archive_set_error(a, EIO, "the archive's source failed");
    return ARCHIVE_FATAL;
  }
}

class Reader {  // owns the libarchive handle
 public:
  Reader() : a_(archive_read_new()) {
    if (!a_) throw std::bad_alloc();
    // Plain tar only (every dialect): no compression filters, no other formats.
    archive_read_support_format_tar(a_);
  }
  ~Reader() { archive_read_free(a_); }
  Reader(const Reader&) = delete;
  Reader& operator=(const Reader&) = delete;
  archive* get() const { return a_; }
  std::string error() const {
    const char* e = archive_error_string(a_);
    return e ? e : "unknown error";
  }

 private:
  archive* a_;
};

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
    // What the file system takes (NAME_MAX 255, PATH_MAX 4096 with the destination's own path).
    if (part.size() > 255)
      throw DataError(where + ": a path component of " + std::to_string(part.size()) + " bytes (at most 255)");
    if (!part.empty() && part != ".") parts.push_back(part);
    start = end + 1;
  }
  if (name.size() > 3000)
    throw DataError(where + ": a path of " + std::to_string(name.size()) + " bytes (at most 3000)");
  return parts;
}

std::string joined(const std::vector<std::string>& parts, std::size_t count) {
  std::string s;
  for (std::size_t i = 0; i < count; ++i) s += (i ? "/" : "") + parts[i];
  return s;
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
    if (fs::is_symlink(status))
      throw DataError(where + ": refusing to write through the symlink " + joined(parts, i + 1));
    if (!fs::exists(status)) {
      fs::create_directory(p, ec);
      if (ec) throw Error("tar: cannot create the directory " + joined(parts, i + 1) + ": " + ec.message());
    } else if (!fs::is_directory(status)) {
      throw DataError(where + ": " + joined(parts, i + 1) + " exists and is not a directory");
    }
  }
  return p;
}

// A new regular file, never opened through a symlink; written at offsets, so the
// holes of a sparse entry stay holes.
class OutputFile {
 public:
  OutputFile(const fs::path& target, const std::string& relative, const std::string& where) : relative_(relative) {
    std::error_code ec;
    const auto status = fs::symlink_status(target, ec);
    if (fs::is_symlink(status) || fs::is_directory(status))
      throw DataError(where + ": " + relative + " already exists as a " +
                      (fs::is_symlink(status) ? "symlink" : "directory"));
    fs::remove(target, ec);  // a later duplicate replaces the file (and never writes into a hard link)
    fd_ = ::open(target.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0644);
    if (fd_ < 0) throw Error("tar: cannot create " + relative + ": " + std::strerror(errno));
  }
  ~OutputFile() {
    if (fd_ >= 0) ::close(fd_);
  }
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;

  void write_at(const char* data, std::size_t size, std::uint64_t offset) {
    while (size > 0) {
      const ssize_t n = ::pwrite(fd_, data, size, static_cast<off_t>(offset));
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) throw Error("tar: cannot write " + relative_ + ": " + std::strerror(errno));
      data += n;
      size -= static_cast<std::size_t>(n);
      offset += static_cast<std::uint64_t>(n);
    }
  }
  // Sets the final size (a sparse file may end in a hole) and closes.
  void finish(std::uint64_t size) {
    const bool ok = ::ftruncate(fd_, static_cast<off_t>(size)) == 0;
    const int closed = ::close(fd_);
    fd_ = -1;
    if (!ok || closed != 0) throw Error("tar: cannot write " + relative_ + ": " + std::strerror(errno));
  }

 private:
  std::string relative_;
  int fd_ = -1;
};

// What is skipped: anything that is neither a regular file nor a directory.
std::string skipped_kind(archive_entry* entry) {
  if (archive_entry_hardlink(entry)) return "hard link";
  switch (archive_entry_filetype(entry)) {
    case AE_IFLNK:
      return "symlink";
    case AE_IFCHR:
      return "character device";
    case AE_IFBLK:
      return "block device";
    case AE_IFIFO:
      return "fifo";
    case AE_IFSOCK:
      return "socket";
    default: {
      char text[32];
      std::snprintf(text, sizeof text, "type 0%o", static_cast<unsigned>(archive_entry_filetype(entry)));
      return text;
    }
  }
}

void check_limits(std::uint64_t size, const TarExtractReport& report, const TarLimits& limits,
                  const std::string& where) {
  if (size > limits.max_file_bytes)
    throw DataError(where + ": " + std::to_string(size) + " bytes, over the max_file_bytes limit of " +
                    std::to_string(limits.max_file_bytes));
  if (size > limits.max_total_bytes - std::min(report.bytes, limits.max_total_bytes))
    throw DataError(where + ": extracted size would exceed the max_total_bytes limit of " +
                    std::to_string(limits.max_total_bytes));
}

}  // namespace

TarExtractReport extract_tar(const TarSource& source, const fs::path& destination, const TarLimits& limits,
                             const std::string& archive_name) {
  std::error_code ec;
  fs::create_directories(destination, ec);
  if (ec) throw Error("tar: cannot create the destination folder: " + ec.message());
  const std::string file = "tar: " + archive_name;
  SourceState state;
  state.source = &source;
  Reader reader;
  archive* a = reader.get();
  const auto rethrow_source_error = [&] {
    if (state.error) std::rethrow_exception(state.error);
  };
  // A failure once the source has ended is a truncation, whatever libarchive's words.
  const auto read_error = [&](const std::string& where) {
    rethrow_source_error();
    if (state.ended)
      return DataError(where + ": truncated archive (it ends at byte " + std::to_string(state.bytes) + ": " +
                       reader.error() + ")");
    return DataError(where + ": " + reader.error());
  };

  if (archive_read_open(a, &state, nullptr, read_callback, nullptr) != ARCHIVE_OK) {
    rethrow_source_error();
    std::string why = state.bytes == 0       ? "empty"
                      : state.bytes < kBlock ? "shorter than one tar header"
                                             : reader.error();
    if (state.bytes >= 2 && state.first[0] == 0x1f && state.first[1] == 0x8b)
      why += "; the data is gzip-compressed, send the uncompressed .tar";
    throw DataError(file + ": not a tar archive (" + why + ")");
  }

  TarExtractReport report;
  std::uint64_t entries = 0;
  std::vector<char> unused;
  for (;;) {
    archive_entry* entry = nullptr;
    const int r = archive_read_next_header(a, &entry);
    rethrow_source_error();
    if (r == ARCHIVE_EOF) {
      // libarchive also ends cleanly at a cut between two entries; a whole
      // archive has its end-of-archive zero blocks after the last entry.
      if (archive_filter_bytes(a, 0) <= archive_read_header_position(a))
        throw DataError(file + ": truncated archive (no end-of-archive marker after " + std::to_string(entries) +
                        " entries)");
      break;
    }
    if (r != ARCHIVE_OK && r != ARCHIVE_WARN) {  // ARCHIVE_RETRY included: a damaged header
      throw read_error(file + ": damaged header at byte " + std::to_string(archive_read_header_position(a)) +
                       " (after " + std::to_string(entries) + " entries)");
    }
    const char* raw_name = archive_entry_pathname(entry);
    if (!raw_name) throw DataError(file + ": entry " + std::to_string(entries + 1) + " has no readable path");
    const std::string name = raw_name;
    const std::string where = file + ": entry '" + (name.size() > 200 ? name.substr(0, 200) + "...'" : name + "'");
    if (++entries > limits.max_entries)
      throw DataError(where + ": too many entries (limit " + std::to_string(limits.max_entries) + ")");
    const auto parts = safe_components(name, where);
    const bool regular = archive_entry_filetype(entry) == AE_IFREG && !archive_entry_hardlink(entry);
    const bool directory = archive_entry_filetype(entry) == AE_IFDIR && !archive_entry_hardlink(entry);

    if (directory) {
      if (parts.empty()) continue;  // "./": the destination itself
      make_directories(destination, parts, parts.size(), where);
      ++report.directories;
    } else if (regular) {
      if (parts.empty()) throw DataError(where + ": empty file name");
      if (!archive_entry_size_is_set(entry) || archive_entry_size(entry) < 0)
        throw DataError(where + ": no file size in its header");
      const auto size = static_cast<std::uint64_t>(archive_entry_size(entry));
      check_limits(size, report, limits, where);
      const fs::path parent = make_directories(destination, parts, parts.size() - 1, where);
      OutputFile out(parent / parts.back(), joined(parts, parts.size()), where);
      for (;;) {
        const void* data = nullptr;
        std::size_t n = 0;
        la_int64_t offset = 0;
        const int d = archive_read_data_block(a, &data, &n, &offset);
        rethrow_source_error();
        if (d == ARCHIVE_EOF) break;
        if (d != ARCHIVE_OK && d != ARCHIVE_WARN) throw read_error(where);
        if (offset < 0 || static_cast<std::uint64_t>(offset) + n > size)
          throw DataError(where + ": data beyond the entry's size of " + std::to_string(size) + " bytes");
        out.write_at(static_cast<const char*>(data), n, static_cast<std::uint64_t>(offset));
      }
      out.finish(size);
      ++report.files;
      report.bytes += size;
    } else {  // links, devices, fifos, sockets: never created
      ++report.skipped;
      if (report.skipped_names.size() < TarExtractReport::kMaxSkippedNames)
        report.skipped_names.push_back(name + " (" + skipped_kind(entry) + ")");
      // libarchive skips whatever data such an entry carries at the next header.
    }
  }
  report.archive_bytes = state.bytes;
  return report;
}

TarExtractReport extract_tar(const fs::path& archive, const fs::path& destination, const TarLimits& limits,
                             const std::function<void(std::uint64_t, std::uint64_t)>& progress) {
  std::error_code ec;
  const std::uint64_t total = fs::file_size(archive, ec);
  std::ifstream in(archive, std::ios::binary);
  if (ec || !in) throw DataError("tar: cannot open archive " + archive.string());
  std::uint64_t done = 0;
  const TarSource source = [&](char* buffer, std::size_t size) {
    in.read(buffer, static_cast<std::streamsize>(size));
    const auto n = static_cast<std::size_t>(in.gcount());
    if (n == 0 && in.bad()) throw Error("tar: cannot read " + archive.string());
    done += n;
    if (progress) progress(done, total);
    return n;
  };
  TarExtractReport report = extract_tar(source, destination, limits, archive.string());
  if (progress) progress(total, total);  // whatever follows the end-of-archive marker is not read
  return report;
}

}  // namespace orbatlas
