#pragma once
// The JSON of a recording's run (`orbatlas run --stats`, `orbatlas localize
// --stats`): the SlamStats keys (wire/stats_json.h) and skipped_frames,
// late_frames, peak_rss_mb, wall_s, failed, ate_rmse_m and ate_align, session,
// atlas{loaded_maps, loaded_keyframes, load_s}, black_out{...}, checkpoints{...}.
#include <nlohmann/json.hpp>

#include "core/pipeline/dataset_runner.h"

namespace orbatlas {

nlohmann::json to_json(const DatasetRunReport& report);

}  // namespace orbatlas
