#pragma once
// The simulated scene: textured planar rectangles (quads) in the world frame.
// A quad is origin + a * edge_u + b * edge_v for a, b in [0, 1]; its texture
// maps a to texture columns and b to rows.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <memory>
#include <vector>

#include "core/sim/texture.h"

namespace orbatlas::sim {

struct Quad {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Vector3d edge_u = Eigen::Vector3d::UnitX();
  Eigen::Vector3d edge_v = Eigen::Vector3d::UnitY();  // orthogonal to edge_u
  int texture = 0;                                    // index into World::textures
  float shade = 1.0f;                                 // brightness factor (fixed lighting per face)

  Eigen::Vector3d normal() const { return edge_u.cross(edge_v).normalized(); }
  Eigen::Vector3d corner(int i) const;  // 0: origin, 1: +u, 2: +u+v, 3: +v
};

// Axis-aligned box: its faces become quads (the bottom one is left out when the
// box stands on the floor).
struct Box {
  Eigen::Vector3d min = Eigen::Vector3d::Zero(), max = Eigen::Vector3d::Ones();
};

class World {
 public:
  // Textures are shared read-only between renderers (and threads).
  int add_texture(Texture texture);
  void add_quad(const Quad& quad) { quads_.push_back(quad); }
  // Adds a box with one texture per face; `with_bottom` adds the floor face;
  // `sparse`: textures of the real look (TextureRequest::sparse).
  void add_box(const Box& box, TextureStyle style, std::uint64_t seed, double texel_size_m, bool with_bottom,
               bool sparse = false);

  const std::vector<Quad>& quads() const { return quads_; }
  const Texture& texture(int id) const { return *textures_[static_cast<std::size_t>(id)]; }
  std::size_t texture_count() const { return textures_.size(); }
  std::size_t texel_count() const;

 private:
  std::vector<Quad> quads_;
  std::vector<std::shared_ptr<const Texture>> textures_;
};

}  // namespace orbatlas::sim
