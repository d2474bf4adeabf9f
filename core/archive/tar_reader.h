#pragma once
// Safe extraction of uploaded tar archives (ustar, GNU and pax; see docs/archive.md).
// Entries that would land outside the destination, and anything but regular files
// and directories, are never created.
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
  std::vector<std::string> skipped_names;  // the first kMaxSkippedNames, e.g. "link (symlink)"
  static constexpr std::size_t kMaxSkippedNames = 20;
};

// Extracts archive into destination (created if missing). Regular files and
// directories are written; symlinks, hard links, devices, fifos and unknown entry
// types are skipped and reported. Throws DataError naming the entry for an unsafe
// path (absolute or with a ".." component), a bad header checksum, a truncated
// archive, an exceeded limit, or a file that is not a tar archive at all. On error,
// files already extracted remain: the caller deletes the destination.
// progress receives archive bytes read / archive size.
TarExtractReport extract_tar(
    const std::filesystem::path& archive, const std::filesystem::path& destination, const TarLimits& limits = {},
    const std::function<void(std::uint64_t bytes_done, std::uint64_t bytes_total)>& progress = {});

}  // namespace orbatlas
