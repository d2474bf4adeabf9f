#pragma once
// Procedural surface textures: deterministic from a seed, never repeating,
// rich in corners and blobs at many scales (what feature detectors need), with
// a mip-map pyramid so that far surfaces do not alias into flickering noise.
#include <cstdint>
#include <opencv2/core/mat.hpp>
#include <vector>

namespace orbatlas::sim {

struct Texture {
  std::vector<cv::Mat> levels;  // CV_8UC1; level 0 full resolution, each next cv::pyrDown of the previous
  double texel_size_m = 0.005;  // edge of one level-0 texel on the surface
};

enum class TextureStyle {
  kClutter,  // noise + shapes of mixed size: walls, floors, generic surfaces
  kMachine,  // panels, bolts and labels: machines and boxes
  kUniform,  // one grey level (test markers)
};

struct TextureRequest {
  double width_m = 1.0, height_m = 1.0;
  double texel_size_m = 0.005;  // grows when the texture would exceed max_texels per side
  int max_texels = 4096;
  TextureStyle style = TextureStyle::kClutter;
  std::uint64_t seed = 1;
  std::uint8_t uniform_value = 255;  // kUniform only
  // The `real` look (look.h): large weakly textured areas (smooth shading, faint
  // grain, low-contrast patches) with sparse high-contrast details (marks,
  // labels, tape strips, bolts), as real walls, floors and machines show.
  bool sparse = false;
};

Texture make_texture(const TextureRequest& request);

// Adds the mip levels to levels[0].
void build_mipmaps(Texture& texture);

}  // namespace orbatlas::sim
