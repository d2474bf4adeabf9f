#pragma once
// A single-camera session that localises in the atlas's stored maps: tracking
// in localisation mode (docs/tracking.md) on frames of one image: every frame
// is relocalised against the maps until a place is recognised, then tracked
// with the motion model and the local map; lost again, it relocalises again.
// It never makes a keyframe, a map point or a map (a single camera has no
// metric scale of its own: mapping needs the stereo rig), so the maps it
// reads stay as they were.
#include <functional>
#include <memory>
#include <mutex>
#include <opencv2/core/mat.hpp>
#include <vector>

#include "core/io/settings.h"
#include "core/map/atlas.h"
#include "core/slam/session_slam.h"
#include "core/slam/session_wiring.h"
#include "core/slam/tracked_frames.h"
#include "core/tracking/frame_relocalizer.h"
#include "core/tracking/mono_frontend.h"
#include "core/tracking/tracker.h"
#include "core/vocabulary/vocabulary.h"

namespace orbatlas {

struct MonoLocalizerOptions {
  TrackerOptions tracker;  // localization_only is forced on

  // Throws Error naming the first value out of range.
  void check() const;
};

class MonoLocalizer final : public SessionSlam {
 public:
  // `atlas` and `vocabulary` must outlive it. Uses the settings' first camera.
  // Of the wiring only may_enter_map applies (nothing is mapped or merged).
  MonoLocalizer(Atlas& atlas, const SlamSettings& settings, const Vocabulary& vocabulary,
                MonoLocalizerOptions options = {}, SessionWiring wiring = {});
  ~MonoLocalizer() override;
  MonoLocalizer(const MonoLocalizer&) = delete;
  MonoLocalizer& operator=(const MonoLocalizer&) = delete;

  // One image (`right` must be empty).
  TrackResult process(TimestampNs t_ns, const cv::Mat& left, const cv::Mat& right = cv::Mat()) override;
  void finish() override;
  std::vector<FrameAnchor> anchors_from(std::size_t first) const override;
  std::optional<FrameAnchor> last_anchor() const override { return frames_.last_anchor(); }
  SlamStats stats() const override;
  std::size_t worker_errors() const override { return frames_.errors().errors; }

 private:
  Atlas& atlas_;
  MonoFrontend frontend_;
  FrameCamera cam_;
  std::unique_ptr<NoKeyframes> sink_;
  std::unique_ptr<FrameRelocalizer> relocalizer_;
  std::unique_ptr<Tracker> tracker_;
  bool finished_ = false;
  TrackedFrames frames_;
};

}  // namespace orbatlas
