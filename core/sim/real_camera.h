#pragma once
// The camera of the simulator's `real` look: auto exposure (exposure time and
// gain chosen for the scene's illumination, drifting over time and differing
// between the two cameras), then, on the radiance the renderer averaged over
// the exposure time (motion blur), vignetting, lens softness, signal-dependent
// noise and clipping to 8 bits. Deterministic from its seed.
#include <cstdint>
#include <opencv2/core/mat.hpp>

#include "core/common/timestamp.h"
#include "core/sim/look.h"

namespace orbatlas::sim {

struct Exposure {
  double exposure_s = 0.003;
  double gain = 1.0;
  double brightness = 1.0;  // multiplies the clean radiance (1: the clean look's brightness)
};

class RealCamera {
 public:
  // `camera_index` 0 or 1 (the two cameras of the rig drift differently).
  RealCamera(const RealCameraOptions& options, int width, int height, int camera_index, std::uint64_t seed);

  Exposure exposure_at(TimestampNs t) const;
  // How many renders to average over the exposure for an image moving at
  // `motion_px_per_s` (at least 1).
  int subframes(double motion_px_per_s, double exposure_s) const;
  // `radiance`: CV_32FC1 mean of the renders, on the clean grey scale. Writes
  // the CV_8UC1 image the camera delivers.
  void develop(const cv::Mat& radiance, const Exposure& exposure, cv::Mat& image, std::uint64_t noise_seed) const;

 private:
  RealCameraOptions options_;
  double phase1_ = 0.0, phase2_ = 0.0, offset_ = 1.0;
  cv::Mat vignette_;  // CV_32FC1 brightness factor per pixel
};

}  // namespace orbatlas::sim
