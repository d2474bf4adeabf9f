#include "core/server/atlas_service_options.h"

#include <cmath>

#include "core/common/error.h"

namespace orbatlas {

void AtlasServiceOptions::check() const {
  ORBATLAS_CHECK(!db.empty(), "the server needs a database path (--db)");
  ORBATLAS_CHECK(max_live_sessions > 0, "server: max_live_sessions must be > 0, not " << max_live_sessions);
  ORBATLAS_CHECK(!std::isnan(idle_timeout_s), "server: idle_timeout_s is not a number");
  ORBATLAS_CHECK(
      std::isfinite(finish_refinement_wait_s) && finish_refinement_wait_s >= 0.0 && finish_refinement_wait_s <= 3600.0,
      "server: finish_refinement_wait_s must be in 0..3600, not " << finish_refinement_wait_s);
  ORBATLAS_CHECK(loop_queue > 0, "server: loop_queue must be > 0, not " << loop_queue);
  ORBATLAS_CHECK(background_nice >= 0 && background_nice <= 19,
                 "server: background_nice must be in 0..19, not " << background_nice);
  ORBATLAS_CHECK(std::isfinite(max_maps_wait_ms) && max_maps_wait_ms >= 0.0 && max_maps_wait_ms <= 10000.0,
                 "server: max_maps_wait_ms must be in 0..10000, not " << max_maps_wait_ms);
  slam.check();
  merging.check();
  checkpoints.check();
  replica.check();
}

}  // namespace orbatlas
