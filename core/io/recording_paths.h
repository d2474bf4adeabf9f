#pragma once
// The files a recording's lists name (EuRoC's cam*/data.csv, TUM's rgb.txt and
// depth.txt), resolved inside the recording. An uploaded recording is confined:
// a name that is absolute, climbs out with "..", or leads out of the
// recording's folder through a link is refused (DataError naming the list's
// file and line), so an upload never reads another upload's files or the
// server's. A local recording may name what it likes (its user can read it anyway).
#include <filesystem>
#include <optional>
#include <string_view>

namespace orbatlas {

struct RecordingConfinement {
  // The recording's folder; empty: not confined.
  std::filesystem::path root;
};

// `dir / name`; when confined, throws DataError("<list>:<line>: ...") if it leaves `root`.
std::filesystem::path recording_file(const std::filesystem::path& dir, std::string_view name,
                                     const RecordingConfinement& confinement, const std::filesystem::path& list,
                                     int line);

}  // namespace orbatlas
