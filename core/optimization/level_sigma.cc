#include "core/optimization/level_sigma.h"

#include <cmath>

#include "core/common/error.h"

namespace orbatlas {

std::vector<double> pyramid_level_sigma2(double scale_factor, int n_levels) {
  ORBATLAS_CHECK(scale_factor >= 1.0 && n_levels > 0,
                 "pyramid_level_sigma2: bad scale factor " << scale_factor << " or level count " << n_levels);
  std::vector<double> sigma2(static_cast<std::size_t>(n_levels), 1.0);
  for (std::size_t level = 1; level < sigma2.size(); ++level)
    sigma2[level] = sigma2[level - 1] * scale_factor * scale_factor;
  return sigma2;
}

void check_level_sigma2(const std::vector<double>& level_sigma2, const char* area) {
  ORBATLAS_CHECK(!level_sigma2.empty(), area << ": level_sigma2 must have at least one level");
  for (std::size_t level = 0; level < level_sigma2.size(); ++level)
    ORBATLAS_CHECK(std::isfinite(level_sigma2[level]) && level_sigma2[level] > 0.0,
                   area << ": level_sigma2[" << level << "] must be finite and > 0, not " << level_sigma2[level]);
}

}  // namespace orbatlas
