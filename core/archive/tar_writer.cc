#include "core/archive/tar_writer.h"

#include <archive.h>
#include <archive_entry.h>

#include <algorithm>
#include <chrono>
#include <exception>
#include <fstream>
#include <system_error>
#include <vector>

#include "core/common/error.h"

namespace orbatlas {
namespace {

constexpr std::size_t kChunk = 64 * 1024;

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

}  // namespace

// libarchive's writer with our sink. Not in the header: it needs <archive.h>.
class TarArchiveWriter {
 public:
  TarSink sink;
  archive* a = nullptr;
  std::uint64_t bytes = 0;
  bool finished = false;
  bool discard = false;  // set before freeing an unfinished archive: nothing more reaches the sink
  std::exception_ptr sink_error;

  explicit TarArchiveWriter(TarSink s) : sink(std::move(s)), a(archive_write_new()) {
    if (!a) throw std::bad_alloc();
    // pax restricted: ustar headers, pax records only where ustar cannot hold a
    // value; no blocking (the output is exactly the entries and the end marker).
    if (archive_write_set_format_pax_restricted(a) != ARCHIVE_OK ||
        archive_write_set_bytes_per_block(a, 0) != ARCHIVE_OK ||
        archive_write_open(a, this, nullptr, &TarArchiveWriter::write_callback, nullptr) != ARCHIVE_OK) {
      const std::string why = archive_error_string(a) ? archive_error_string(a) : "unknown error";
      archive_write_free(a);
      throw Error("tar: cannot start an archive: " + why);
    }
  }
  ~TarArchiveWriter() {
    discard = true;
    archive_write_free(a);
  }

  // libarchive writes through this C callback: the sink's exception is kept and
  // rethrown by check(), never thrown across C frames.
  static la_ssize_t write_callback(archive*, void* client, const void* buffer, size_t length) {
    auto* self = static_cast<TarArchiveWriter*>(client);
    if (self->discard) return static_cast<la_ssize_t>(length);
    try {
      self->sink(static_cast<const char*>(buffer), length);
      self->bytes += length;
      return static_cast<la_ssize_t>(length);
    } catch (...) {
      self->sink_error = std::current_exception();
      return -1;
    }
  }

  void check(bool ok, const std::string& what) const {
    if (sink_error) std::rethrow_exception(sink_error);
    if (!ok) throw Error("tar: " + what + ": " + (archive_error_string(a) ? archive_error_string(a) : "unknown error"));
  }

  // An entry's header; its data follows (write_data), or finish_entry() fills
  // what was not written with zeros (used to measure an archive's size).
  void header(const std::string& path, bool directory, std::uint64_t size, std::int64_t mtime) {
    ORBATLAS_CHECK(!finished, "TarWriter: entry '" << path << "' added after finish()");
    archive_entry* entry = archive_entry_new();
    if (!entry) throw std::bad_alloc();
    archive_entry_copy_pathname(entry, path.c_str());
    archive_entry_set_filetype(entry, directory ? AE_IFDIR : AE_IFREG);
    archive_entry_set_perm(entry, directory ? 0755 : 0644);
    archive_entry_set_size(entry, static_cast<la_int64_t>(size));
    archive_entry_set_mtime(entry, std::max<std::int64_t>(mtime, 0), 0);
    archive_entry_set_uid(entry, 0);
    archive_entry_set_gid(entry, 0);
    const int r = archive_write_header(a, entry);
    archive_entry_free(entry);
    check(r == ARCHIVE_OK || r == ARCHIVE_WARN, "cannot write the header of '" + path + "'");
  }
  void write_data(const char* data, std::size_t size, const std::string& path) {
    const la_ssize_t n = archive_write_data(a, data, size);
    check(n == static_cast<la_ssize_t>(size), "cannot write the data of '" + path + "'");
  }
  void finish_entry(const std::string& path) {
    const int r = archive_write_finish_entry(a);
    check(r == ARCHIVE_OK || r == ARCHIVE_WARN, "cannot end the entry '" + path + "'");
  }
  void close() {
    if (finished) return;
    finished = true;
    check(archive_write_close(a) == ARCHIVE_OK, "cannot end the archive");
  }
};

TarWriter::TarWriter(TarSink sink) {
  ORBATLAS_CHECK(static_cast<bool>(sink), "TarWriter: no sink");
  impl_ = std::make_unique<TarArchiveWriter>(std::move(sink));
}

TarWriter::~TarWriter() = default;

std::uint64_t TarWriter::bytes_written() const { return impl_->bytes; }

void TarWriter::add_file(const std::string& archive_path, const std::filesystem::path& source) {
  check_archive_path(archive_path);
  std::error_code ec;
  ORBATLAS_CHECK(std::filesystem::is_regular_file(source, ec), "tar: not a readable regular file: " << source);
  const std::uint64_t size = std::filesystem::file_size(source, ec);
  ORBATLAS_CHECK(!ec, "tar: cannot stat " << source << ": " << ec.message());
  std::ifstream in(source, std::ios::binary);
  ORBATLAS_CHECK(in, "tar: cannot open " << source);
  impl_->header(archive_path, false, size, mtime_seconds(source));
  // Exactly `size` bytes follow the header, whatever happens to the file meanwhile.
  std::vector<char> buffer(kChunk);
  for (std::uint64_t left = size; left > 0;) {
    const auto want = static_cast<std::streamsize>(std::min<std::uint64_t>(left, kChunk));
    in.read(buffer.data(), want);
    ORBATLAS_CHECK(in.gcount() == want, "tar: cannot read " << source << " (read error, or it shrank while archived)");
    impl_->write_data(buffer.data(), static_cast<std::size_t>(want), archive_path);
    left -= static_cast<std::uint64_t>(want);
  }
  impl_->finish_entry(archive_path);
}

void TarWriter::add_directory_entry(const std::string& archive_path, std::int64_t mtime) {
  const std::string path = directory_path(archive_path);
  check_archive_path(path);
  impl_->header(path, true, 0, mtime);
  impl_->finish_entry(path);
}

void TarWriter::finish() { impl_->close(); }

namespace {

// The bytes an archive of these entries takes: the same writer with the data left
// out (libarchive fills each entry's data with zeros), the bytes only counted.
std::uint64_t measured_size(const std::vector<TreeEntry>& entries) {
  TarArchiveWriter counter([](const char*, std::size_t) {});
  for (const auto& e : entries) {
    const std::string path = e.directory ? directory_path(e.relative.generic_string()) : e.relative.generic_string();
    counter.header(path, e.directory, e.size, mtime_seconds(e.source));
    counter.finish_entry(path);
  }
  counter.close();
  return counter.bytes;
}

}  // namespace

std::uint64_t tar_entry_bytes(const std::string& archive_path, std::uint64_t data_size) {
  TarArchiveWriter counter([](const char*, std::size_t) {});
  const bool directory = !archive_path.empty() && archive_path.back() == '/';
  counter.header(archive_path, directory, directory ? 0 : data_size, 0);
  counter.finish_entry(archive_path);
  return counter.bytes;
}

void write_directory_tar(const std::filesystem::path& root, const TarSink& sink, const TarProgress& progress) {
  const auto entries = list_tree(root);
  const std::uint64_t total = measured_size(entries);
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

std::uint64_t directory_tar_size(const std::filesystem::path& root) { return measured_size(list_tree(root)); }

}  // namespace orbatlas
