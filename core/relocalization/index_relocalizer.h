#pragma once
// Tracking's relocaliser over the atlas-wide keyframe index (core/relocalization), for
// the sessions' trackers.
#include <functional>

#include "core/map/keyframe_index.h"
#include "core/relocalization/relocalizer.h"
#include "core/tracking/frame_relocalizer.h"
#include "core/vocabulary/vocabulary.h"

namespace orbatlas {

class IndexRelocalizer final : public FrameRelocalizer {
 public:
  // `vocabulary`, `index` and the camera must outlive it. `may_enter` (may be
  // empty) refuses maps the session must stay out of.
  IndexRelocalizer(const Vocabulary& vocabulary, const KeyframeIndex& index, const FrameCamera& cam, Pose3 T_b_c,
                   std::function<bool(MapId)> may_enter);
  std::optional<Relocalized> relocalize(Frame& frame) override;

 private:
  const Vocabulary& vocabulary_;
  const KeyframeIndex& index_;
  const FrameCamera cam_;
  const Pose3 T_b_c_;
  RelocalizationOptions options_;
};

}  // namespace orbatlas
