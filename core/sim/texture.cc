#include "core/sim/texture.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <random>

namespace orbatlas::sim {
namespace {

using Rng = std::mt19937_64;

double uniform(Rng& rng, double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); }
int uniform_int(Rng& rng, int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng); }

// Smooth value noise: random grey levels on a coarse grid, upsampled bicubically,
// summed over octaves. Gives the low-frequency shading of real surfaces.
void add_value_noise(cv::Mat& img, Rng& rng, double cell_texels, double amplitude) {
  const int gw = std::max(2, static_cast<int>(img.cols / cell_texels) + 2);
  const int gh = std::max(2, static_cast<int>(img.rows / cell_texels) + 2);
  cv::Mat grid(gh, gw, CV_32F);
  for (int y = 0; y < gh; ++y)
    for (int x = 0; x < gw; ++x) grid.at<float>(y, x) = static_cast<float>(uniform(rng, -amplitude, amplitude));
  cv::Mat up;
  cv::resize(grid, up, cv::Size(static_cast<int>(gw * cell_texels), static_cast<int>(gh * cell_texels)), 0, 0, cv::INTER_CUBIC);
  cv::Mat roi = up(cv::Rect(0, 0, img.cols, img.rows));
  cv::Mat img_f;
  img.convertTo(img_f, CV_32F);
  img_f += roi;
  img_f.convertTo(img, CV_8U);
}

cv::Scalar grey(Rng& rng, int lo = 10, int hi = 245) { return cv::Scalar(uniform_int(rng, lo, hi)); }

// Random shapes of one size class; sizes in texels. Filled and outlined
// rectangles, rotated boxes, circles, line segments and dots.
void add_shapes(cv::Mat& img, Rng& rng, int count, double min_size, double max_size) {
  for (int n = 0; n < count; ++n) {
    const cv::Point2f c(static_cast<float>(uniform(rng, 0, img.cols)), static_cast<float>(uniform(rng, 0, img.rows)));
    const double s = std::exp(uniform(rng, std::log(min_size), std::log(max_size)));
    const int kind = uniform_int(rng, 0, 9);
    const int thickness = kind % 2 == 0 ? cv::FILLED : std::max(1, static_cast<int>(s * uniform(rng, 0.05, 0.2)));
    switch (kind) {
      case 0:
      case 1:
      case 2: {  // axis-aligned rectangle
        const cv::Point2f h(static_cast<float>(s * uniform(rng, 0.3, 1.0)), static_cast<float>(s * uniform(rng, 0.3, 1.0)));
        cv::rectangle(img, c - h, c + h, grey(rng), thickness, cv::LINE_8);
        break;
      }
      case 3:
      case 4: {  // rotated rectangle
        const cv::RotatedRect r(c, cv::Size2f(static_cast<float>(s), static_cast<float>(s * uniform(rng, 0.2, 1.0))),
                                static_cast<float>(uniform(rng, 0, 180)));
        cv::Point2f pts[4];
        r.points(pts);
        std::vector<cv::Point> poly(pts, pts + 4);
        if (thickness == cv::FILLED)
          cv::fillConvexPoly(img, poly, grey(rng), cv::LINE_AA);
        else
          cv::polylines(img, poly, true, grey(rng), thickness, cv::LINE_AA);
        break;
      }
      case 5:
      case 6:  // circle / ring
        cv::circle(img, c, std::max(1, static_cast<int>(s * 0.5)), grey(rng), thickness, cv::LINE_AA);
        break;
      case 7: {  // triangle
        std::vector<cv::Point> tri;
        for (int k = 0; k < 3; ++k)
          tri.emplace_back(static_cast<int>(c.x + s * uniform(rng, -0.7, 0.7)), static_cast<int>(c.y + s * uniform(rng, -0.7, 0.7)));
        cv::fillConvexPoly(img, tri, grey(rng), cv::LINE_AA);
        break;
      }
      default: {  // line segment
        const double a = uniform(rng, 0, CV_PI);
        const cv::Point2f d(static_cast<float>(s * std::cos(a)), static_cast<float>(s * std::sin(a)));
        cv::line(img, c - d, c + d, grey(rng), std::max(1, static_cast<int>(s * uniform(rng, 0.02, 0.1))), cv::LINE_AA);
        break;
      }
    }
  }
}

// Machine surfaces: a panel grid with frames, bolts and label-like blocks.
void add_machine_panels(cv::Mat& img, Rng& rng, double texel_m) {
  const double panel_m = uniform(rng, 0.25, 0.8);
  const int step = std::max(8, static_cast<int>(panel_m / texel_m));
  for (int y0 = uniform_int(rng, 0, step); y0 < img.rows; y0 += step) {
    for (int x0 = uniform_int(rng, 0, step); x0 < img.cols; x0 += step) {
      const cv::Rect r(x0, y0, step - 2, step - 2);
      cv::rectangle(img, r, grey(rng, 20, 90), std::max(1, step / 40));
      const int bolt = std::max(1, step / 30);
      for (const cv::Point p : {r.tl() + cv::Point(3 * bolt, 3 * bolt), cv::Point(r.br().x - 3 * bolt, r.y + 3 * bolt)})
        cv::circle(img, p, bolt, grey(rng, 200, 250), cv::FILLED, cv::LINE_AA);
      if (uniform(rng, 0, 1) < 0.5) {
        const cv::Point tl(x0 + uniform_int(rng, step / 8, step / 2), y0 + uniform_int(rng, step / 8, step / 2));
        cv::rectangle(img, tl, tl + cv::Point(uniform_int(rng, step / 8, step / 3), uniform_int(rng, step / 16, step / 6)),
                      grey(rng), cv::FILLED);
      }
    }
  }
}

}  // namespace

void build_mipmaps(Texture& texture) {
  texture.levels.resize(1);
  while (texture.levels.back().cols > 4 && texture.levels.back().rows > 4) {
    cv::Mat next;
    cv::pyrDown(texture.levels.back(), next);
    texture.levels.push_back(next);
  }
}

Texture make_texture(const TextureRequest& req) {
  Texture tex;
  double texel = req.texel_size_m;
  const double longest = std::max(req.width_m, req.height_m);
  if (longest / texel > req.max_texels) texel = longest / req.max_texels;
  tex.texel_size_m = texel;
  const int w = std::max(4, static_cast<int>(std::ceil(req.width_m / texel)));
  const int h = std::max(4, static_cast<int>(std::ceil(req.height_m / texel)));
  Rng rng(req.seed * 0x9E3779B97F4A7C15ULL + 0x632BE59BD9B4E5ULL);
  if (req.style == TextureStyle::kUniform) {
    tex.levels.emplace_back(h, w, CV_8UC1, cv::Scalar(req.uniform_value));
    build_mipmaps(tex);
    return tex;
  }
  cv::Mat img(h, w, CV_8UC1, cv::Scalar(uniform_int(rng, 70, 180)));
  const double area_m2 = req.width_m * req.height_m;
  const double m = 1.0 / texel;  // texels per metre
  if (req.style == TextureStyle::kMachine) add_machine_panels(img, rng, texel);
  // Shapes per square metre, per size class (large, medium, small, tiny).
  add_shapes(img, rng, static_cast<int>(std::ceil(area_m2 * 1.5)), 0.3 * m, 1.2 * m);
  add_shapes(img, rng, static_cast<int>(std::ceil(area_m2 * 12)), 0.08 * m, 0.3 * m);
  add_shapes(img, rng, static_cast<int>(std::ceil(area_m2 * 40)), 0.025 * m, 0.08 * m);
  if (texel < 0.012) add_shapes(img, rng, static_cast<int>(std::ceil(area_m2 * 60)), 0.012 * m, 0.025 * m);
  add_value_noise(img, rng, 0.5 * m, 25.0);
  tex.levels.push_back(img);
  build_mipmaps(tex);
  return tex;
}

}  // namespace orbatlas::sim
