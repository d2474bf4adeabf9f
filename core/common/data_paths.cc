#include "core/common/data_paths.h"

#include <cstdlib>

namespace orbatlas {
namespace {
std::filesystem::path from_env_or(const char* var, const char* fallback) {
  const char* v = std::getenv(var);
  return (v != nullptr && *v != '\0') ? std::filesystem::path(v) : std::filesystem::path(fallback);
}
}  // namespace

std::filesystem::path shipped_data_dir() { return from_env_or("ORBATLAS_DATA_DIR", ORBATLAS_DEFAULT_DATA_DIR); }

std::filesystem::path shipped_config_dir() { return from_env_or("ORBATLAS_CONFIG_DIR", ORBATLAS_DEFAULT_CONFIG_DIR); }

std::filesystem::path shipped_viewer_dir() { return from_env_or("ORBATLAS_VIEWER_DIR", ORBATLAS_DEFAULT_VIEWER_DIR); }

std::filesystem::path three_js_dir() { return from_env_or("ORBATLAS_THREE_JS_DIR", ORBATLAS_DEFAULT_THREE_JS_DIR); }

namespace {
// `variable` when set, else shared/data/<name> beside the source tree (which
// sits in <work>/<checkout>); empty when the folder is not there.
std::optional<std::filesystem::path> shared_data_dir(const char* variable, const char* name) {
  std::error_code ec;
  if (const char* v = std::getenv(variable); v != nullptr && *v != '\0') {
    if (std::filesystem::is_directory(v, ec)) return std::filesystem::path(v);
    return std::nullopt;
  }
  const auto candidate =
      std::filesystem::path(ORBATLAS_DEFAULT_DATA_DIR).parent_path().parent_path() / "shared" / "data" / name;
  if (std::filesystem::is_directory(candidate, ec)) return candidate;
  return std::nullopt;
}
}  // namespace

std::optional<std::filesystem::path> shared_euroc_dir() { return shared_data_dir("ORBATLAS_SHARED_EUROC", "euroc"); }

std::optional<std::filesystem::path> shared_kitti_dir() { return shared_data_dir("ORBATLAS_SHARED_KITTI", "kitti"); }

}  // namespace orbatlas
