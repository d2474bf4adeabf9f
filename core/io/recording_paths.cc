#include "core/io/recording_paths.h"

#include <string>
#include <system_error>

#include "core/common/error.h"

namespace orbatlas {
namespace fs = std::filesystem;

namespace {

// Whether `path` is `root` or below it (both normalised).
bool inside(const fs::path& path, const fs::path& root) {
  auto p = path.begin();
  for (auto r = root.begin(); r != root.end(); ++r, ++p) {
    if (r->empty()) continue;  // a trailing separator
    if (p == path.end() || *p != *r) return false;
  }
  return true;
}

}  // namespace

fs::path recording_file(const fs::path& dir, std::string_view name, const RecordingConfinement& confinement,
                        const fs::path& list, int line) {
  const fs::path given{std::string(name)};
  const fs::path file = dir / given;
  if (confinement.root.empty()) return file;
  const auto refuse = [&](const std::string& why) {
    throw DataError(list.string() + ":" + std::to_string(line) + ": the file name '" +
                    std::string(name.substr(0, 200)) + "' " + why +
                    " (an uploaded recording names files inside its own folder only)");
  };
  if (given.is_absolute() || given.has_root_name() || given.has_root_directory()) refuse("is an absolute path");
  for (const auto& part : given)
    if (part == "..") refuse("climbs out with '..'");
  std::error_code ec;
  const fs::path root = fs::weakly_canonical(confinement.root, ec);
  if (ec) refuse("cannot be checked: " + ec.message());
  const fs::path resolved = fs::weakly_canonical(file, ec);  // links followed
  if (ec) refuse("cannot be checked: " + ec.message());
  if (!inside(resolved, root)) refuse("leads out of the recording's folder through a link");
  return file;
}

}  // namespace orbatlas
