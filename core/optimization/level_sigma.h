#pragma once
// Squared position uncertainty of a keypoint per pyramid level: sigma^2 =
// scale_factor^(2 * level), as ORB-SLAM's mvLevelSigma2 (OrbExtractor::level_sigma2
// gives the same numbers for the extractor actually used).
#include <vector>

namespace orbatlas {

std::vector<double> pyramid_level_sigma2(double scale_factor = 1.2, int n_levels = 8);

// Throws Error unless `level_sigma2` has at least one level and every value is
// finite and > 0 (the options' check() of the bundle adjustments; `area` starts the message).
void check_level_sigma2(const std::vector<double>& level_sigma2, const char* area);

}  // namespace orbatlas
