#pragma once
// How the simulator's images look. `clean`: the original renders (dense
// procedural texture everywhere, constant exposure, uniform Gaussian noise).
// `real`: what real cameras in a real hall do that clean renders do not —
// large weakly textured surfaces with sparse high-contrast details, auto
// exposure that drifts over time and differs between the two cameras,
// vignetting, motion blur over the exposure time along the true trajectory,
// signal-dependent noise, clipping, darker MH_04/MH_05 and, as an option, a
// calibration slightly off from the one written to sensor.yaml. Its IMU is the
// realistic one (imu_synthesizer.h, realistic_imu_errors()).
// See docs/simulator.md.
#include <cstdint>
#include <string>

namespace orbatlas::sim {

enum class Look { kClean, kReal };
const char* look_name(Look look);
Look parse_look(const std::string& name);  // throws Error for an unknown name

// The camera side of the `real` look (core/sim/real_camera.h).
struct RealCameraOptions {
  // Scene illumination relative to a well-lit hall (1). Auto exposure
  // compensates with exposure time first (more motion blur), then gain (more
  // noise); what it cannot compensate leaves the image darker.
  double illumination = 1.0;
  double base_exposure_ms = 3.0;  // exposure at illumination 1
  double max_exposure_ms = 10.0;
  double max_gain = 1.6;
  // Auto exposure lags and hunts: the brightness it delivers drifts around the
  // target by this relative amplitude (two slow sinusoids per camera, periods
  // in seconds), and the two cameras' gains differ by up to `stereo_mismatch`.
  double drift = 0.22;
  double drift_period_s = 6.0;
  double stereo_mismatch = 0.12;
  double vignetting = 0.4;       // brightness lost at the image corners (cos^4-like falloff)
  double optics_blur_px = 0.55;  // Gaussian sigma of the lens' softness
  double read_noise = 1.4;       // grey levels at gain 1
  double shot_noise = 0.06;      // variance per grey level of signal at gain 1
  int max_blur_subframes = 8;    // renders averaged over the exposure time
  double blur_px_per_subframe = 1.0;

  // Throws Error naming the first value out of range.
  void check() const;
};

// The `real` look as a whole; defaults per sequence from real_look_for().
struct RealLookOptions {
  RealCameraOptions camera;
  bool sparse_textures = true;  // weakly textured surfaces with sparse details (texture.h)
  // Scale of the render-vs-sensor.yaml calibration error (0: none, the default:
  // an error of the rig is not the tracker's to fix, and a disparity bias of a
  // few tenths of a pixel alone triples the ATE of a dark MH_04; --calib-error 1
  // adds it, see sequence_simulator.cc).
  double calibration_error = 0.0;

  // Throws Error naming the first value out of range.
  void check() const;
};

// MH_04 and MH_05 are the dark sequences of the real Machine Hall.
RealLookOptions real_look_for(const std::string& sequence);

}  // namespace orbatlas::sim
