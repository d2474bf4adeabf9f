#include "core/loop/probe_frame.h"

namespace orbatlas {

Frame probe_frame(const KeyFrame& keyframe) {
  Frame f;
  f.t_ns = keyframe.timestamp_ns();
  f.features = keyframe.features();
  const std::size_t n = keyframe.slot_count();
  f.depth.resize(n);
  f.u_right.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    f.depth[i] = keyframe.depth(i);
    f.u_right[i] = keyframe.u_right(i);
  }
  f.grid = keyframe.grid();
  f.bow = keyframe.bow();
  f.feature_vector = keyframe.feature_vector();
  f.T_w_b = keyframe.T_w_b();
  f.has_pose = true;
  f.map_points.assign(n, nullptr);
  f.outlier.assign(n, false);
  return f;
}

int associated_count(const Frame& probe) {
  int n = 0;
  for (std::size_t i = 0; i < probe.size(); ++i)
    if (probe.map_points[i] && !probe.outlier[i]) ++n;
  return n;
}

}  // namespace orbatlas
