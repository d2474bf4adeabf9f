#pragma once
#include <filesystem>

namespace orbatlas {

// The vocabulary shipped with orbatlas (data/vocabulary/orbatlas_k10_l5.vocab).
std::filesystem::path default_vocabulary_path();

}  // namespace orbatlas
