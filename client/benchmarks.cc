// What the benchmarks' options may hold (each run_*_bench checks its options first).
#include "client/benchmarks.h"

#include <cmath>

#include <opencv2/imgcodecs.hpp>

#include "core/common/error.h"

namespace orbatlas::cli {

cv::Mat read_gray(const std::filesystem::path& path) {
  cv::Mat img = cv::imread(path.string(), cv::IMREAD_GRAYSCALE);
  if (img.empty()) throw DataError("cannot read image " + path.string());
  return img;
}

void RenderBenchOptions::check() const {
  ORBATLAS_CHECK(frames >= 1, "bench render: frames (--frames) must be >= 1, not " << frames);
}

void FeatureBenchOptions::check() const {
  ORBATLAS_CHECK(frames >= 1, "bench features: frames (--frames) must be >= 1, not " << frames);
  ORBATLAS_CHECK(database_keyframes >= 1,
                 "bench features: database_keyframes (--database-keyframes) must be >= 1, not " << database_keyframes);
}

void AtlasStoreBenchOptions::check() const {
  ORBATLAS_CHECK(keyframes >= 2, "bench atlas-store: keyframes (--keyframes) must be >= 2, not " << keyframes);
  ORBATLAS_CHECK(keypoints >= 1, "bench atlas-store: keypoints (--keypoints) must be >= 1, not " << keypoints);
  ORBATLAS_CHECK(
      points_per_keyframe >= 0,
      "bench atlas-store: points_per_keyframe (--points-per-keyframe) must be >= 0, not " << points_per_keyframe);
}

void AlignmentBenchOptions::check() const {
  ORBATLAS_CHECK(problems >= 1, "bench alignment: problems (--problems) must be >= 1, not " << problems);
}

void StereoBenchOptions::check() const {
  ORBATLAS_CHECK(frames >= 1, "bench stereo: frames (--frames) must be >= 1, not " << frames);
  ORBATLAS_CHECK(std::isfinite(depth_map_factor) && depth_map_factor > 0.0,
                 "bench stereo: depth_map_factor (--depth-map-factor) must be > 0, not " << depth_map_factor);
}

void PlaceBenchOptions::check() const {
  ORBATLAS_CHECK(every >= 1, "bench place: every (--every) must be >= 1, not " << every);
  ORBATLAS_CHECK(std::isfinite(revisit_m) && revisit_m > 0.0,
                 "bench place: revisit_m (--revisit-m) must be a finite value > 0, not " << revisit_m);
  ORBATLAS_CHECK(std::isfinite(revisit_deg) && revisit_deg > 0.0,
                 "bench place: revisit_deg (--revisit-deg) must be a finite value > 0, not " << revisit_deg);
}

}  // namespace orbatlas::cli
