#pragma once
// Where the files shipped with orbatlas live (data/ and config/ of the source
// tree by default). ORBATLAS_DATA_DIR / ORBATLAS_CONFIG_DIR override them, and
// the real EuRoC extras (../shared/data/euroc) are found via ORBATLAS_SHARED_EUROC
// or next to the source tree; they are optional.
#include <filesystem>
#include <optional>

namespace orbatlas {

std::filesystem::path shipped_data_dir();
std::filesystem::path shipped_config_dir();
// The map viewer's page (viewer/; ORBATLAS_VIEWER_DIR overrides) and three.js
// (Debian's libjs-three, /usr/share/javascript/three; ORBATLAS_THREE_JS_DIR).
std::filesystem::path shipped_viewer_dir();
std::filesystem::path three_js_dir();

// The optional folder of real EuRoC data (../shared/data/euroc); empty if absent.
std::optional<std::filesystem::path> shared_euroc_dir();
// The optional folder of real KITTI odometry data (../shared/data/kitti, or
// ORBATLAS_SHARED_KITTI); empty if absent.
std::optional<std::filesystem::path> shared_kitti_dir();

}  // namespace orbatlas
