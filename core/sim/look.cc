#include "core/sim/look.h"

#include <cmath>

#include "core/common/error.h"

namespace orbatlas::sim {

void RealCameraOptions::check() const {
  ORBATLAS_CHECK(std::isfinite(illumination) && illumination > 0.0,
                 "real look: illumination must be a finite value > 0, not " << illumination);
  ORBATLAS_CHECK(std::isfinite(base_exposure_ms) && base_exposure_ms > 0.0,
                 "real look: base_exposure_ms must be a finite value > 0, not " << base_exposure_ms);
  ORBATLAS_CHECK(max_exposure_ms >= base_exposure_ms * 0.1,
                 "real look: max_exposure_ms must be >= 0.1 * base_exposure_ms = " << base_exposure_ms * 0.1 << ", not "
                                                                                   << max_exposure_ms);
  ORBATLAS_CHECK(max_gain >= 1.0, "real look: max_gain must be >= 1, not " << max_gain);
  ORBATLAS_CHECK(std::isfinite(drift) && drift >= 0.0, "real look: drift must be a finite value >= 0, not " << drift);
  ORBATLAS_CHECK(std::isfinite(drift_period_s) && drift_period_s > 0.0,
                 "real look: drift_period_s must be a finite value > 0, not " << drift_period_s);
  ORBATLAS_CHECK(std::isfinite(stereo_mismatch) && stereo_mismatch >= 0.0,
                 "real look: stereo_mismatch must be a finite value >= 0, not " << stereo_mismatch);
  ORBATLAS_CHECK(vignetting >= 0.0 && vignetting <= 1.0, "real look: vignetting must be in [0, 1], not " << vignetting);
  ORBATLAS_CHECK(std::isfinite(optics_blur_px) && optics_blur_px >= 0.0,
                 "real look: optics_blur_px must be a finite value >= 0, not " << optics_blur_px);
  ORBATLAS_CHECK(std::isfinite(read_noise) && read_noise >= 0.0,
                 "real look: read_noise must be a finite value >= 0, not " << read_noise);
  ORBATLAS_CHECK(std::isfinite(shot_noise) && shot_noise >= 0.0,
                 "real look: shot_noise must be a finite value >= 0, not " << shot_noise);
  ORBATLAS_CHECK(max_blur_subframes >= 1, "real look: max_blur_subframes must be >= 1, not " << max_blur_subframes);
  ORBATLAS_CHECK(std::isfinite(blur_px_per_subframe) && blur_px_per_subframe > 0.0,
                 "real look: blur_px_per_subframe must be a finite value > 0, not " << blur_px_per_subframe);
}

void RealLookOptions::check() const {
  camera.check();
  ORBATLAS_CHECK(std::isfinite(calibration_error) && calibration_error >= 0.0,
                 "real look: calibration_error (--calib-error) must be a finite value >= 0, not " << calibration_error);
}

const char* look_name(Look look) { return look == Look::kReal ? "real" : "clean"; }

Look parse_look(const std::string& name) {
  if (name == "clean") return Look::kClean;
  if (name == "real") return Look::kReal;
  throw Error("unknown simulator look '" + name + "' (clean or real)");
}

RealLookOptions real_look_for(const std::string& sequence) {
  RealLookOptions o;
  if (sequence == "MH_04" || sequence == "MH_05") o.camera.illumination = 0.12;
  return o;
}

}  // namespace orbatlas::sim
