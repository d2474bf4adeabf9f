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
  cv::resize(grid, up, cv::Size(static_cast<int>(gw * cell_texels), static_cast<int>(gh * cell_texels)), 0, 0,
             cv::INTER_CUBIC);
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
        const cv::Point2f h(static_cast<float>(s * uniform(rng, 0.3, 1.0)),
                            static_cast<float>(s * uniform(rng, 0.3, 1.0)));
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
          tri.emplace_back(static_cast<int>(c.x + s * uniform(rng, -0.7, 0.7)),
                           static_cast<int>(c.y + s * uniform(rng, -0.7, 0.7)));
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
        cv::rectangle(img, tl,
                      tl + cv::Point(uniform_int(rng, step / 8, step / 3), uniform_int(rng, step / 16, step / 6)),
                      grey(rng), cv::FILLED);
      }
    }
  }
}

// Shapes of one size class drawn with a grey near `base` (low contrast).
void add_faint_shapes(cv::Mat& img, Rng& rng, int count, double min_size, double max_size, int base, int contrast) {
  for (int n = 0; n < count; ++n) {
    const cv::Point2f c(static_cast<float>(uniform(rng, 0, img.cols)), static_cast<float>(uniform(rng, 0, img.rows)));
    const double s = std::exp(uniform(rng, std::log(min_size), std::log(max_size)));
    const int g =
        std::clamp(base + (uniform_int(rng, 0, 1) ? 1 : -1) * uniform_int(rng, contrast / 3, contrast), 0, 255);
    if (uniform_int(rng, 0, 2) == 0) {
      cv::circle(img, c, std::max(1, static_cast<int>(s * 0.5)), cv::Scalar(g), cv::FILLED, cv::LINE_AA);
    } else {
      const cv::RotatedRect r(c, cv::Size2f(static_cast<float>(s), static_cast<float>(s * uniform(rng, 0.3, 1.0))),
                              static_cast<float>(uniform(rng, 0, 180)));
      cv::Point2f pts[4];
      r.points(pts);
      std::vector<cv::Point> poly(pts, pts + 4);
      cv::fillConvexPoly(img, poly, cv::Scalar(g), cv::LINE_AA);
    }
  }
}

// A dark or bright grey far from the surface's base: the sparse details.
cv::Scalar extreme_grey(Rng& rng, int base) {
  const bool dark = base > 128 ? uniform_int(rng, 0, 4) > 0 : uniform_int(rng, 0, 4) == 0;
  return cv::Scalar(dark ? uniform_int(rng, 10, 45) : uniform_int(rng, 200, 250));
}

// Tape strips on floors and walls (long, thin, high contrast), some with small
// light patches along them (like the markers on real lab floors).
void add_strips(cv::Mat& img, Rng& rng, int count, double texels_per_m, int base) {
  for (int n = 0; n < count; ++n) {
    const cv::Point2f c(static_cast<float>(uniform(rng, 0, img.cols)), static_cast<float>(uniform(rng, 0, img.rows)));
    const double length = uniform(rng, 0.6, 2.5) * texels_per_m, width = uniform(rng, 0.03, 0.08) * texels_per_m;
    const float angle = static_cast<float>(uniform(rng, 0, 180));
    const cv::RotatedRect r(c, cv::Size2f(static_cast<float>(length), static_cast<float>(width)), angle);
    cv::Point2f pts[4];
    r.points(pts);
    std::vector<cv::Point> poly(pts, pts + 4);
    const cv::Scalar g = extreme_grey(rng, base);
    cv::fillConvexPoly(img, poly, g, cv::LINE_AA);
    if (uniform(rng, 0, 1) < 0.4) {
      const cv::Scalar patch(g[0] < 128 ? uniform_int(rng, 190, 240) : uniform_int(rng, 20, 60));
      const int patches = static_cast<int>(length / std::max(4.0, 2.5 * width));
      const double a = angle * CV_PI / 180.0;
      for (int k = 0; k < patches; ++k) {
        const double along = uniform(rng, -0.45, 0.45) * length, across = uniform(rng, -0.25, 0.25) * width;
        const cv::Point2f p(c.x + static_cast<float>(along * std::cos(a) - across * std::sin(a)),
                            c.y + static_cast<float>(along * std::sin(a) + across * std::cos(a)));
        const cv::RotatedRect bit(p, cv::Size2f(static_cast<float>(width * 0.35), static_cast<float>(width * 0.15)),
                                  static_cast<float>(uniform(rng, 0, 180)));
        bit.points(pts);
        std::vector<cv::Point> q(pts, pts + 4);
        cv::fillConvexPoly(img, q, patch, cv::LINE_AA);
      }
    }
  }
}

// Small high-contrast details: marks, labels, bolts, screws.
void add_details(cv::Mat& img, Rng& rng, int count, double min_size, double max_size, int base) {
  for (int n = 0; n < count; ++n) {
    const cv::Point2f c(static_cast<float>(uniform(rng, 0, img.cols)), static_cast<float>(uniform(rng, 0, img.rows)));
    const double s = std::exp(uniform(rng, std::log(min_size), std::log(max_size)));
    const cv::Scalar g = extreme_grey(rng, base);
    switch (uniform_int(rng, 0, 3)) {
      case 0: {  // label: a block with a few text-like lines
        const cv::Point2f h(static_cast<float>(s * 0.6), static_cast<float>(s * uniform(rng, 0.25, 0.5)));
        cv::rectangle(img, c - h, c + h, g, cv::FILLED, cv::LINE_8);
        const cv::Scalar ink(g[0] > 128 ? 30 : 220);
        for (int k = 0; k < 3; ++k) {
          const float y = c.y - h.y * 0.6f + static_cast<float>(k) * h.y * 0.6f;
          cv::line(img, cv::Point2f(c.x - h.x * 0.8f, y),
                   cv::Point2f(c.x + h.x * static_cast<float>(uniform(rng, -0.2, 0.8)), y), ink,
                   std::max(1, static_cast<int>(s * 0.06)), cv::LINE_AA);
        }
        break;
      }
      case 1:  // bolt / screw
        cv::circle(img, c, std::max(1, static_cast<int>(s * 0.2)), g, cv::FILLED, cv::LINE_AA);
        break;
      case 2: {  // mark: a cross or an L
        const float k = static_cast<float>(s * 0.5);
        const int t = std::max(1, static_cast<int>(s * 0.1));
        cv::line(img, c - cv::Point2f(k, 0), c + cv::Point2f(k, 0), g, t, cv::LINE_AA);
        cv::line(img, c - cv::Point2f(0, k), c + cv::Point2f(0, uniform_int(rng, 0, 1) ? k : 0.0f), g, t, cv::LINE_AA);
        break;
      }
      default: {  // blotch
        const cv::RotatedRect r(c, cv::Size2f(static_cast<float>(s), static_cast<float>(s * uniform(rng, 0.2, 0.8))),
                                static_cast<float>(uniform(rng, 0, 180)));
        cv::Point2f pts[4];
        r.points(pts);
        std::vector<cv::Point> poly(pts, pts + 4);
        cv::fillConvexPoly(img, poly, g, cv::LINE_AA);
        break;
      }
    }
  }
}

// Machine panels in the real look: frames close to the panel grey, bright bolts
// at two corners, a label on some panels.
void add_sparse_panels(cv::Mat& img, Rng& rng, double texel_m, int base) {
  const double panel_m = uniform(rng, 0.4, 1.2);
  const int step = std::max(8, static_cast<int>(panel_m / texel_m));
  for (int y0 = uniform_int(rng, 0, step); y0 < img.rows; y0 += step) {
    for (int x0 = uniform_int(rng, 0, step); x0 < img.cols; x0 += step) {
      const cv::Rect r(x0, y0, step - 2, step - 2);
      cv::rectangle(img, r, cv::Scalar(std::clamp(base - uniform_int(rng, 10, 30), 0, 255)), std::max(1, step / 60));
      const int bolt = std::max(1, step / 40);
      if (uniform(rng, 0, 1) < 0.6)
        for (const cv::Point p :
             {r.tl() + cv::Point(3 * bolt, 3 * bolt), cv::Point(r.br().x - 3 * bolt, r.y + 3 * bolt)})
          cv::circle(img, p, bolt, cv::Scalar(uniform_int(rng, 200, 250)), cv::FILLED, cv::LINE_AA);
      if (uniform(rng, 0, 1) < 0.2) {
        const cv::Point tl(x0 + uniform_int(rng, step / 8, step / 2), y0 + uniform_int(rng, step / 8, step / 2));
        cv::rectangle(img, tl,
                      tl + cv::Point(uniform_int(rng, step / 8, step / 3), uniform_int(rng, step / 16, step / 6)),
                      extreme_grey(rng, base), cv::FILLED);
      }
    }
  }
}

cv::Mat make_sparse_image(const TextureRequest& req, int w, int h, double texel, Rng& rng) {
  const int base = uniform_int(rng, 45, 205);
  cv::Mat img(h, w, CV_8UC1, cv::Scalar(base));
  const double area_m2 = req.width_m * req.height_m;
  const double m = 1.0 / texel;              // texels per metre
  add_value_noise(img, rng, 1.5 * m, 24.0);  // broad shading
  add_faint_shapes(img, rng, static_cast<int>(std::ceil(area_m2 * 0.6)), 0.3 * m, 1.5 * m, base, 35);
  add_faint_shapes(img, rng, static_cast<int>(std::ceil(area_m2 * 4.0)), 0.05 * m, 0.3 * m, base, 18);
  if (req.style == TextureStyle::kMachine) add_sparse_panels(img, rng, texel, base);
  const double detail_density = req.style == TextureStyle::kMachine ? 9.0 : 4.5;
  add_details(img, rng, static_cast<int>(std::ceil(area_m2 * detail_density)), 0.03 * m, 0.2 * m, base);
  if (req.style == TextureStyle::kClutter) add_strips(img, rng, static_cast<int>(std::ceil(area_m2 * 0.1)), m, base);
  add_value_noise(img, rng, 0.3 * m, 6.0);                      // stains
  if (texel < 0.012) add_value_noise(img, rng, 0.02 * m, 3.0);  // faint grain
  return img;
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
  if (req.sparse) {
    tex.levels.push_back(make_sparse_image(req, w, h, texel, rng));
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
