#pragma once
// Squared position uncertainty of a keypoint per pyramid level: sigma^2 =
// scale_factor^(2 * level), as ORB-SLAM's mvLevelSigma2 (OrbExtractor::level_sigma2
// gives the same numbers for the extractor actually used).
#include <vector>

namespace orbatlas {

std::vector<double> pyramid_level_sigma2(double scale_factor = 1.2, int n_levels = 8);

}  // namespace orbatlas
