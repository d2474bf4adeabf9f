#include "core/relocalization/index_relocalizer.h"

namespace orbatlas {

IndexRelocalizer::IndexRelocalizer(const Vocabulary& vocabulary, const KeyframeIndex& index, const FrameCamera& cam,
                                   Pose3 T_b_c, std::function<bool(MapId)> may_enter)
    : vocabulary_(vocabulary), index_(index), cam_(cam), T_b_c_(T_b_c) {
  options_.may_enter = std::move(may_enter);
}

std::optional<Relocalized> IndexRelocalizer::relocalize(Frame& frame) {
  const RelocalizationResult r = orbatlas::relocalize(frame, vocabulary_, index_, cam_, T_b_c_, options_);
  if (!r.success) return std::nullopt;
  return Relocalized{r.map, r.keyframe};
}

}  // namespace orbatlas
