#pragma once
// The simulated Machine Hall: one world for every MH sequence (same seed, same
// hall), so sessions rendered from different sequences can be merged later. A
// hall enclosing all five real trajectories, machines and crates standing on the
// floor, pillars and wall fixtures, every surface with its own procedural texture.
#include <cstdint>
#include <vector>

#include "core/geometry/trajectory.h"
#include "core/sim/world.h"

namespace orbatlas::sim {

struct MachineHallOptions {
  std::uint64_t seed = 1;
  double clearance_m = 0.9;      // no object closer than this to any trajectory
  double margin_m = 4.0;         // walls this far beyond the trajectories
  int machine_count = 70;        // target number of machines/crates
  double texel_size_m = 0.005;   // finest texture detail
  bool sparse_textures = false;  // the real look's textures (TextureRequest::sparse)

  // Throws Error naming the first value out of range.
  void check() const;
};

struct HallBounds {
  Eigen::Vector3d min, max;
};

// `trajectories`: the paths that must stay free (normally all five MH ground truths).
World build_machine_hall(const std::vector<Trajectory>& trajectories, const MachineHallOptions& options,
                         HallBounds* bounds = nullptr);

// All five Machine Hall ground truths from the shipped data.
std::vector<Trajectory> load_machine_hall_trajectories();

}  // namespace orbatlas::sim
