#include "core/sim/machine_hall.h"

#include <algorithm>
#include <cmath>
#include <random>

#include "core/common/error.h"
#include "core/sim/euroc_sequences.h"

namespace orbatlas::sim {
namespace {

double distance_to_box(const Eigen::Vector3d& p, const Box& b) {
  const Eigen::Vector3d d = (b.min - p).cwiseMax(p - b.max).cwiseMax(Eigen::Vector3d::Zero());
  return d.norm();
}

class FreeSpace {
 public:
  FreeSpace(const std::vector<Trajectory>& trajectories, double clearance) : clearance_(clearance) {
    for (const auto& tr : trajectories)
      for (std::size_t i = 0; i < tr.size(); i += 10) points_.push_back(tr[i].pose.t);  // 20 Hz is dense enough
  }
  bool allows(const Box& b) const {
    return std::none_of(points_.begin(), points_.end(),
                        [&](const Eigen::Vector3d& p) { return distance_to_box(p, b) < clearance_; });
  }

 private:
  double clearance_;
  std::vector<Eigen::Vector3d> points_;
};

// One wall/floor/ceiling quad facing into the hall.
void add_surface(World& world, const Eigen::Vector3d& origin, const Eigen::Vector3d& u, const Eigen::Vector3d& v,
                 std::uint64_t seed, double texel, float shade, bool sparse) {
  TextureRequest req;
  req.width_m = u.norm();
  req.height_m = v.norm();
  req.texel_size_m = texel;
  req.style = TextureStyle::kClutter;
  req.seed = seed;
  req.sparse = sparse;
  Quad q;
  q.origin = origin;
  q.edge_u = u;
  q.edge_v = v;
  q.texture = world.add_texture(make_texture(req));
  q.shade = shade;
  world.add_quad(q);
}

}  // namespace

void MachineHallOptions::check() const {
  ORBATLAS_CHECK(std::isfinite(clearance_m) && clearance_m >= 0.0,
                 "machine hall: clearance_m must be a finite value >= 0, not " << clearance_m);
  ORBATLAS_CHECK(std::isfinite(margin_m) && margin_m >= 0.0,
                 "machine hall: margin_m must be a finite value >= 0, not " << margin_m);
  ORBATLAS_CHECK(machine_count >= 0, "machine hall: machine_count must be >= 0, not " << machine_count);
  ORBATLAS_CHECK(std::isfinite(texel_size_m) && texel_size_m > 0.0,
                 "machine hall: texel_size_m must be a finite value > 0, not " << texel_size_m);
}

World build_machine_hall(const std::vector<Trajectory>& trajectories, const MachineHallOptions& options,
                         HallBounds* bounds_out) {
  options.check();
  ORBATLAS_CHECK(!trajectories.empty(), "machine hall: no trajectories given");
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e18), hi = Eigen::Vector3d::Constant(-1e18);
  for (const auto& tr : trajectories)
    for (const auto& s : tr) {
      lo = lo.cwiseMin(s.pose.t);
      hi = hi.cwiseMax(s.pose.t);
    }
  const HallBounds hall{Eigen::Vector3d(lo.x() - options.margin_m, lo.y() - options.margin_m, lo.z() - 1.0),
                        Eigen::Vector3d(hi.x() + options.margin_m, hi.y() + options.margin_m, hi.z() + 3.0)};
  if (bounds_out != nullptr) *bounds_out = hall;

  World world;
  const Eigen::Vector3d size = hall.max - hall.min;
  const Eigen::Vector3d ex(size.x(), 0, 0), ey(0, size.y(), 0), ez(0, 0, size.z());
  const Eigen::Vector3d& o = hall.min;
  std::uint64_t seed = options.seed * 1000003ULL;
  // Floor, ceiling and four walls, normals pointing into the hall.
  add_surface(world, o, ex, ey, ++seed, options.texel_size_m, 0.85f, options.sparse_textures);      // floor (+z)
  add_surface(world, o + ez, ey, ex, ++seed, options.texel_size_m, 0.7f, options.sparse_textures);  // ceiling (-z)
  add_surface(world, o, ez, ex, ++seed, options.texel_size_m, 1.0f, options.sparse_textures);       // y = min wall (+y)
  add_surface(world, o + ey, ex, ez, ++seed, options.texel_size_m, 0.95f,
              options.sparse_textures);                                                             // y = max wall (-y)
  add_surface(world, o, ey, ez, ++seed, options.texel_size_m, 0.9f, options.sparse_textures);       // x = min wall (+x)
  add_surface(world, o + ex, ez, ey, ++seed, options.texel_size_m, 0.8f, options.sparse_textures);  // x = max wall (-x)

  const FreeSpace free(trajectories, options.clearance_m);
  std::mt19937_64 rng(options.seed * 7919ULL + 17ULL);
  auto uni = [&](double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng); };
  const double floor_z = hall.min.z();

  // Pillars along the walls, floor to ceiling.
  for (int i = 0; i < 12; ++i) {
    const bool along_x = i % 2 == 0;
    const double s = 0.4;
    const double a = along_x ? uni(hall.min.x() + 1, hall.max.x() - 1) : uni(hall.min.y() + 1, hall.max.y() - 1);
    const bool near_min = (i / 2) % 2 == 0;
    Box b;
    if (along_x) {
      const double y = near_min ? hall.min.y() + 0.5 : hall.max.y() - 0.5 - s;
      b = {Eigen::Vector3d(a, y, floor_z), Eigen::Vector3d(a + s, y + s, hall.max.z())};
    } else {
      const double x = near_min ? hall.min.x() + 0.5 : hall.max.x() - 0.5 - s;
      b = {Eigen::Vector3d(x, a, floor_z), Eigen::Vector3d(x + s, a + s, hall.max.z())};
    }
    if (free.allows(b))
      world.add_box(b, TextureStyle::kMachine, ++seed, options.texel_size_m, false, options.sparse_textures);
  }

  // Machines and crates on the floor, some with a smaller box on top.
  int placed = 0;
  for (int attempt = 0; attempt < options.machine_count * 60 && placed < options.machine_count; ++attempt) {
    const double w = uni(0.6, 3.0), d = uni(0.6, 3.0), h = uni(0.5, 3.5);
    const double x = uni(hall.min.x() + 0.2, hall.max.x() - 0.2 - w);
    const double y = uni(hall.min.y() + 0.2, hall.max.y() - 0.2 - d);
    const Box b{Eigen::Vector3d(x, y, floor_z), Eigen::Vector3d(x + w, y + d, floor_z + h)};
    if (!free.allows(b)) continue;
    const bool crate = uni(0, 1) < 0.4;
    world.add_box(b, crate ? TextureStyle::kClutter : TextureStyle::kMachine, ++seed, options.texel_size_m, false,
                  options.sparse_textures);
    ++placed;
    if (uni(0, 1) < 0.35) {
      const double tw = w * uni(0.3, 0.7), td = d * uni(0.3, 0.7), th = uni(0.3, 1.2);
      const double tx = x + uni(0, w - tw), ty = y + uni(0, d - td);
      const Box top{Eigen::Vector3d(tx, ty, b.max.z()), Eigen::Vector3d(tx + tw, ty + td, b.max.z() + th)};
      if (free.allows(top))
        world.add_box(top, TextureStyle::kMachine, ++seed, options.texel_size_m, false, options.sparse_textures);
    }
  }
  return world;
}

std::vector<Trajectory> load_machine_hall_trajectories() {
  std::vector<Trajectory> out;
  for (const auto& name : machine_hall_sequence_names()) out.push_back(load_ground_truth(find_sequence(name)));
  return out;
}

}  // namespace orbatlas::sim
