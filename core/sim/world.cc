#include "core/sim/world.h"

#include <cmath>

namespace orbatlas::sim {

Eigen::Vector3d Quad::corner(int i) const {
  switch (i & 3) {
    case 0:
      return origin;
    case 1:
      return origin + edge_u;
    case 2:
      return origin + edge_u + edge_v;
    default:
      return origin + edge_v;
  }
}

int World::add_texture(Texture texture) {
  textures_.push_back(std::make_shared<const Texture>(std::move(texture)));
  return static_cast<int>(textures_.size()) - 1;
}

std::size_t World::texel_count() const {
  std::size_t n = 0;
  for (const auto& t : textures_)
    for (const auto& l : t->levels) n += l.total();
  return n;
}

namespace {
// Fixed lighting: a soft key light from above plus ambient, per face normal.
float face_shade(const Eigen::Vector3d& n) {
  const Eigen::Vector3d light = Eigen::Vector3d(0.3, 0.2, 1.0).normalized();
  return static_cast<float>(0.65 + 0.35 * std::max(0.0, n.dot(light)) + 0.1 * std::abs(n.x()));
}
}  // namespace

void World::add_box(const Box& box, TextureStyle style, std::uint64_t seed, double texel_size_m, bool with_bottom,
                    bool sparse) {
  const Eigen::Vector3d& lo = box.min;
  const Eigen::Vector3d size = box.max - box.min;
  const Eigen::Vector3d ex(size.x(), 0, 0), ey(0, size.y(), 0), ez(0, 0, size.z());
  // Faces with outward normals (edge_u x edge_v points out of the box).
  struct Face {
    Eigen::Vector3d origin, u, v;
  };
  std::vector<Face> faces = {
      {lo, ey, ex},             // bottom (-z)
      {lo + ez, ex, ey},        // top (+z)
      {lo, ex, ez},             // -y
      {lo + ey + ex, -ex, ez},  // +y
      {lo + ey, -ey, ez},       // -x
      {lo + ex, ey, ez},        // +x
  };
  for (std::size_t f = with_bottom ? 0 : 1; f < faces.size(); ++f) {
    TextureRequest req;
    req.width_m = faces[f].u.norm();
    req.height_m = faces[f].v.norm();
    req.texel_size_m = texel_size_m;
    req.style = style;
    req.seed = seed * 16 + f;
    req.sparse = sparse;
    Quad q;
    q.origin = faces[f].origin;
    q.edge_u = faces[f].u;
    q.edge_v = faces[f].v;
    q.texture = add_texture(make_texture(req));
    q.shade = face_shade(q.normal());
    add_quad(q);
  }
}

}  // namespace orbatlas::sim
