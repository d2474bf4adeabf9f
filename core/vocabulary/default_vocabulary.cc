#include "core/vocabulary/default_vocabulary.h"

#include "core/common/data_paths.h"

namespace orbatlas {

std::filesystem::path default_vocabulary_path() { return shipped_data_dir() / "vocabulary" / "orbatlas_k10_l5.vocab"; }

}  // namespace orbatlas
