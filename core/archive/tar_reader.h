#pragma once
// Safe extraction of uploaded tar archives, parsed by libarchive (every tar dialect:
// ustar, GNU, pax, old V7; GNU and pax sparse files; see docs/archive.md). Entries
// that would land outside the destination, and anything but regular files and
// directories, are never created.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace orbatlas {

struct TarLimits {
  std::uint64_t max_total_bytes = 64ull << 30;  // sum of the extracted files' sizes
  std::uint64_t max_entries = 2'000'000;        // entries of any type
  std::uint64_t max_file_bytes = 1ull << 30;    // size of one file
};

struct TarExtractReport {
  std::uint64_t files = 0, directories = 0, bytes = 0, skipped = 0;
  std::uint64_t archive_bytes = 0;         // bytes read from the source
  std::vector<std::string> skipped_names;  // the first kMaxSkippedNames, e.g. "link (symlink)"
  static constexpr std::size_t kMaxSkippedNames = 20;
};

// A source of archive bytes: copies at most `size` bytes into `buffer` and returns
// how many; 0 at the end. May throw (the extraction then throws the same).
using TarSource = std::function<std::size_t(char* buffer, std::size_t size)>;

// Extracts the archive read from `source` into `destination` (created if missing).
// Regular files and directories are written; symlinks, hard links, devices, fifos
// and sockets are skipped and reported. Throws DataError naming `archive_name` and
// the entry for an unsafe path (absolute, or with a ".." component), a damaged
// header, a truncated archive (also one cut between two entries: the end-of-archive
// marker must be there), an exceeded limit, or data that is not a tar archive. On
// error, files already extracted remain: the caller deletes the destination.
// Messages name entries by their path in the archive, never by the destination's.
TarExtractReport extract_tar(const TarSource& source, const std::filesystem::path& destination, const TarLimits& limits,
                             const std::string& archive_name);

// The same from a file; progress receives archive bytes read / archive size.
TarExtractReport extract_tar(
    const std::filesystem::path& archive, const std::filesystem::path& destination, const TarLimits& limits = {},
    const std::function<void(std::uint64_t bytes_done, std::uint64_t bytes_total)>& progress = {});

}  // namespace orbatlas
