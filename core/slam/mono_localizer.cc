#include "core/slam/mono_localizer.h"

#include <chrono>

#include "core/common/error.h"
#include "core/relocalization/index_relocalizer.h"

namespace orbatlas {

void MonoLocalizerOptions::check() const { tracker.check(); }

MonoLocalizer::MonoLocalizer(Atlas& atlas, const SlamSettings& settings, const Vocabulary& vocabulary,
                             MonoLocalizerOptions options, SessionWiring wiring)
    : atlas_(atlas), frontend_(settings), sink_(std::make_unique<NoKeyframes>()) {
  options.check();
  cam_ = frontend_.frame_camera();  // no stereo: bf 0
  const Pose3 T_b_c = frontend_.calibration().T_b_c;
  relocalizer_ = std::make_unique<IndexRelocalizer>(vocabulary, atlas_.keyframe_index(), cam_, T_b_c,
                                                    std::move(wiring.may_enter_map));
  TrackerOptions tracker = options.tracker;
  tracker.localization_only = true;
  tracker.max_frames_between_keyframes = std::max(1, static_cast<int>(std::lround(settings.fps)));
  tracker_ = std::make_unique<Tracker>(atlas_, vocabulary, *sink_, cam_, T_b_c, tracker, relocalizer_.get());
}

MonoLocalizer::~MonoLocalizer() = default;

TrackResult MonoLocalizer::process(TimestampNs t_ns, const cv::Mat& left, const cv::Mat& right) {
  ORBATLAS_CHECK(!finished_, "this localisation session has finished; it takes no more frames");
  ORBATLAS_DATA_CHECK(right.empty(), "a single-camera session takes one image per frame, not a stereo pair");
  const auto start = std::chrono::steady_clock::now();
  // It reads maps other sessions edit: it sees each edit whole.
  return frames_.track(*tracker_, frontend_.make_frame(t_ns, left), atlas_, start);
}

void MonoLocalizer::finish() {
  if (finished_) return;
  finished_ = true;
  tracker_->release_frames();
}

std::vector<FrameAnchor> MonoLocalizer::anchors_from(std::size_t first) const { return frames_.anchors_from(first); }

SlamStats MonoLocalizer::stats() const {
  SlamStats s;
  s.frames = frames_.frames();
  s.tracked = frames_.tracked();
  s.lost = s.frames - s.tracked;
  s.tracking_errors = frames_.errors();
  s.relocalizations = tracker_->relocalizations();
  add_atlas_counts(atlas_, s);
  frames_.report(s);
  return s;
}

}  // namespace orbatlas
