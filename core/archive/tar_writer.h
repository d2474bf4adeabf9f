#pragma once
// Streaming writer of tar archives, on libarchive (POSIX pax, restricted: plain
// ustar headers, with a pax extended header only for what ustar cannot hold, such
// as long paths or files of 8 GiB and more; see docs/archive.md). The archive is
// pushed to a sink in pieces, so a client can send a folder as the body of an HTTP
// request without a temporary file.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>

namespace orbatlas {

using TarSink = std::function<void(const char* data, std::size_t size)>;
using TarProgress = std::function<void(std::uint64_t bytes_done, std::uint64_t bytes_total)>;

class TarArchiveWriter;  // libarchive's writer and our sink (tar_writer.cc)

class TarWriter {
 public:
  explicit TarWriter(TarSink sink);
  ~TarWriter();
  TarWriter(const TarWriter&) = delete;
  TarWriter& operator=(const TarWriter&) = delete;

  // A regular file (mode 0644, mtime of the source), streamed in 64 KiB chunks.
  // archive_path is relative ("mav0/cam0/data/1.png"), without ".." components.
  // Throws Error if the source cannot be read or shrinks while it is read, or if
  // the sink throws; the sink may then already have received part of the entry
  // (the stream is broken).
  void add_file(const std::string& archive_path, const std::filesystem::path& source);

  // A directory entry (mode 0755); a trailing '/' is added if missing.
  void add_directory_entry(const std::string& archive_path, std::int64_t mtime_seconds = 0);

  // Writes the end-of-archive marker (two zero blocks). Idempotent; nothing can be
  // added afterwards.
  void finish();

  std::uint64_t bytes_written() const;

 private:
  std::unique_ptr<TarArchiveWriter> impl_;
};

// Archive size of one entry (its headers, plus data padded to 512-byte blocks),
// exactly as TarWriter writes it.
std::uint64_t tar_entry_bytes(const std::string& archive_path, std::uint64_t data_size);

// Archives every regular file and directory under root, recursively, in sorted path
// order, with paths relative to root (root/mav0/x.png -> "mav0/x.png"); symlinks and
// special files are skipped. progress receives archive bytes written / total.
void write_directory_tar(const std::filesystem::path& root, const TarSink& sink, const TarProgress& progress = {});

// The exact number of bytes write_directory_tar(root, ...) produces, provided the
// tree does not change in between (write_directory_tar throws Error if it did).
std::uint64_t directory_tar_size(const std::filesystem::path& root);

}  // namespace orbatlas
