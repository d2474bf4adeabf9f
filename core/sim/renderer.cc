#include "core/sim/renderer.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <random>

#include "core/common/error.h"

namespace orbatlas::sim {
namespace {

constexpr int kNoiseTableBits = 20;

// log2 accurate to ~0.1 (enough to choose a mip level) without calling log2f.
inline float fast_log2(float x) {
  std::uint32_t bits;
  std::memcpy(&bits, &x, sizeof bits);
  const float exponent = static_cast<float>(static_cast<int>((bits >> 23) & 0xFF) - 127);
  bits = (bits & 0x007FFFFF) | 0x3F800000;  // mantissa in [1, 2)
  float m;
  std::memcpy(&m, &bits, sizeof m);
  return exponent + (m - 1.0f) * (1.3465f - 0.3465f * m);  // quadratic fit of log2 on [1, 2)
}

constexpr int kMaxLevels = 16;

// One mip level, flattened for the inner loop.
struct LevelView {
  const std::uint8_t* data;
  std::size_t step;
  int w1, h1;      // last column and row
  float scale256;  // 256 / 2^level
};

struct Vertex {
  double x, y;  // canvas pixel
};

}  // namespace

void RenderOptions::check() const {
  ORBATLAS_CHECK(std::isfinite(noise_sigma) && noise_sigma >= 0.0,
                 "renderer: noise_sigma must be a finite value >= 0, not " << noise_sigma);
  ORBATLAS_CHECK(std::isfinite(near_m) && near_m > 0.0, "renderer: near_m must be a finite value > 0, not " << near_m);
  ORBATLAS_CHECK(std::isfinite(max_canvas_scale) && max_canvas_scale > 0.0,
                 "renderer: max_canvas_scale must be a finite value > 0, not " << max_canvas_scale);
  ORBATLAS_CHECK(canvas_focal_scale > 0.1 && canvas_focal_scale <= 4.0,
                 "renderer: canvas_focal_scale must be in (0.1, 4], not " << canvas_focal_scale);
}

Renderer::Renderer(const World& world, const Camera& camera, const RenderOptions& options)
    : world_(world), options_(options), width_(camera.width()), height_(camera.height()) {
  options_.check();
  const CameraCalibration cal = camera.calibration();
  fx_ = cal.fx * options_.canvas_focal_scale;
  fy_ = cal.fy * options_.canvas_focal_scale;
  // Normalised canvas coordinates of every image pixel.
  cv::Mat xs(height_, width_, CV_32F), ys(height_, width_, CV_32F);
  double min_x = 1e9, max_x = -1e9, min_y = 1e9, max_y = -1e9;
  const double limit_x = options_.max_canvas_scale * width_ / (2.0 * cal.fx);
  const double limit_y = options_.max_canvas_scale * height_ / (2.0 * cal.fy);
  for (int v = 0; v < height_; ++v) {
    for (int u = 0; u < width_; ++u) {
      const Eigen::Vector3d b = camera.unproject(Eigen::Vector2d(u, v));
      float nx = std::numeric_limits<float>::quiet_NaN(), ny = nx;
      if (b.z() > 1e-6 && std::abs(b.x() / b.z()) < limit_x && std::abs(b.y() / b.z()) < limit_y) {
        nx = static_cast<float>(b.x() / b.z());
        ny = static_cast<float>(b.y() / b.z());
        min_x = std::min(min_x, double(nx));
        max_x = std::max(max_x, double(nx));
        min_y = std::min(min_y, double(ny));
        max_y = std::max(max_y, double(ny));
      }
      xs.at<float>(v, u) = nx;
      ys.at<float>(v, u) = ny;
    }
  }
  ORBATLAS_CHECK(max_x > min_x && max_y > min_y, "renderer: the camera model images no direction");
  constexpr double kMargin = 2.0;
  cx_ = -min_x * fx_ + kMargin;
  cy_ = -min_y * fy_ + kMargin;
  const int cw = static_cast<int>(std::ceil(max_x * fx_ + cx_ + kMargin)) + 1;
  const int ch = static_cast<int>(std::ceil(max_y * fy_ + cy_ + kMargin)) + 1;
  canvas_.create(ch, cw, CV_8UC1);
  zbuffer_.create(ch, cw, CV_32FC1);

  cv::Mat map_x(height_, width_, CV_32F), map_y(height_, width_, CV_32F);
  row_begin_.assign(static_cast<std::size_t>(ch), cw);
  row_end_.assign(static_cast<std::size_t>(ch), 0);
  for (int v = 0; v < height_; ++v) {
    for (int u = 0; u < width_; ++u) {
      const float nx = xs.at<float>(v, u), ny = ys.at<float>(v, u);
      if (std::isnan(nx)) {
        map_x.at<float>(v, u) = -10.0f;  // outside the canvas: border (black)
        map_y.at<float>(v, u) = -10.0f;
        continue;
      }
      const double px = nx * fx_ + cx_, py = ny * fy_ + cy_;
      map_x.at<float>(v, u) = static_cast<float>(px);
      map_y.at<float>(v, u) = static_cast<float>(py);
      const int x0 = static_cast<int>(std::floor(px)), y0 = static_cast<int>(std::floor(py));
      for (int y = std::max(0, y0 - 1); y <= std::min(ch - 1, y0 + 2); ++y) {
        row_begin_[static_cast<std::size_t>(y)] =
            std::max(0, std::min(row_begin_[static_cast<std::size_t>(y)], x0 - 1));
        row_end_[static_cast<std::size_t>(y)] = std::min(cw, std::max(row_end_[static_cast<std::size_t>(y)], x0 + 3));
      }
    }
  }
  cv::convertMaps(map_x, map_y, map1_, map2_, CV_16SC2);

  noise_table_.resize(std::size_t{1} << kNoiseTableBits);
  std::mt19937_64 rng(0xC0FFEE);
  std::normal_distribution<double> normal(0.0, options_.noise_sigma);
  for (auto& n : noise_table_) n = static_cast<std::int16_t>(std::lround(std::clamp(normal(rng), -127.0, 127.0)));
}

void Renderer::render(const Pose3& T_w_c, cv::Mat& image, std::uint64_t noise_seed) {
  canvas_.setTo(cv::Scalar(0));
  zbuffer_.setTo(cv::Scalar(std::numeric_limits<float>::infinity()));
  const Pose3 T_c_w = T_w_c.inverse();
  const Eigen::Matrix3d R_c_w = T_c_w.rotation();
  // Front to back: near surfaces fill the z-buffer first, so hidden pixels of
  // farther ones fail the depth test before any texture is read.
  const Eigen::Vector3d p_w = T_w_c.t;
  draw_order_.clear();
  for (std::size_t i = 0; i < world_.quads().size(); ++i) {
    const Quad& q = world_.quads()[i];
    const Eigen::Vector3d rel = p_w - q.origin;
    const double a = std::clamp(rel.dot(q.edge_u) / q.edge_u.squaredNorm(), 0.0, 1.0);
    const double b = std::clamp(rel.dot(q.edge_v) / q.edge_v.squaredNorm(), 0.0, 1.0);
    draw_order_.emplace_back((q.origin + a * q.edge_u + b * q.edge_v - p_w).squaredNorm(), i);
  }
  std::sort(draw_order_.begin(), draw_order_.end());
  for (const auto& [dist, i] : draw_order_) rasterize_quad(world_.quads()[i], R_c_w, T_c_w.t);
  cv::remap(canvas_, image, map1_, map2_, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
  if (options_.noise_sigma > 0.0) add_noise(image, noise_seed);
}

std::optional<double> Renderer::depth_along(const Eigen::Vector3d& ray_c) const {
  if (ray_c.z() <= 1e-9) return std::nullopt;
  const long x = std::lround(fx_ * ray_c.x() / ray_c.z() + cx_), y = std::lround(fy_ * ray_c.y() / ray_c.z() + cy_);
  if (x < 0 || y < 0 || x >= zbuffer_.cols || y >= zbuffer_.rows) return std::nullopt;
  const float z = zbuffer_.at<float>(static_cast<int>(y), static_cast<int>(x));
  if (!std::isfinite(z)) return std::nullopt;
  return static_cast<double>(z);
}

void Renderer::add_noise(cv::Mat& image, std::uint64_t seed) const {
  const std::size_t mask = noise_table_.size() - 1;
  std::size_t offset = static_cast<std::size_t>(seed * 0x9E3779B97F4A7C15ULL >> 20);
  // A different stride per frame breaks the correlation between frames.
  const std::size_t stride = 1 + 2 * ((seed >> 7) % 61);
  for (int v = 0; v < image.rows; ++v) {
    std::uint8_t* row = image.ptr<std::uint8_t>(v);
    for (int u = 0; u < image.cols; ++u) {
      offset = (offset + stride) & mask;
      const int value = row[u] + noise_table_[offset];
      row[u] = static_cast<std::uint8_t>(value < 0 ? 0 : (value > 255 ? 255 : value));
    }
  }
}

void Renderer::rasterize_quad(const Quad& quad, const Eigen::Matrix3d& R_c_w, const Eigen::Vector3d& t_c_w) {
  const Texture& tex = world_.texture(quad.texture);
  // Corners in the camera frame, clipped against the near plane.
  Eigen::Vector3d corners[4];
  int in_front = 0;
  for (int i = 0; i < 4; ++i) {
    corners[i] = R_c_w * quad.corner(i) + t_c_w;
    in_front += corners[i].z() > options_.near_m ? 1 : 0;
  }
  if (in_front == 0) return;
  Vertex poly[8];
  int n = 0;
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector3d& a = corners[i];
    const Eigen::Vector3d& b = corners[(i + 1) & 3];
    const bool a_in = a.z() > options_.near_m, b_in = b.z() > options_.near_m;
    if (a_in) poly[n++] = {fx_ * a.x() / a.z() + cx_, fy_ * a.y() / a.z() + cy_};
    if (a_in != b_in) {
      const double s = (options_.near_m - a.z()) / (b.z() - a.z());
      const Eigen::Vector3d p = a + s * (b - a);
      poly[n++] = {fx_ * p.x() / p.z() + cx_, fy_ * p.y() / p.z() + cy_};
    }
  }
  double min_y = 1e18, max_y = -1e18, min_x = 1e18, max_x = -1e18;
  for (int i = 0; i < n; ++i) {
    min_y = std::min(min_y, poly[i].y);
    max_y = std::max(max_y, poly[i].y);
    min_x = std::min(min_x, poly[i].x);
    max_x = std::max(max_x, poly[i].x);
  }
  const int rows = canvas_.rows, cols = canvas_.cols;
  if (max_x < 0 || min_x > cols - 1 || max_y < 0 || min_y > rows - 1) return;
  const int y_first = std::max(0, static_cast<int>(std::ceil(min_y - 1e-3)));
  const int y_last = std::min(rows - 1, static_cast<int>(std::floor(max_y + 1e-3)));

  // Plane n . P = d and texture axes in the camera frame; texture coordinates in
  // level-0 texels: s = g_u . P - s0, t = g_v . P - t0.
  const Eigen::Vector3d normal = R_c_w * quad.normal();
  const double d = normal.dot(corners[0]);
  if (std::abs(d) < 1e-9) return;  // camera inside the plane
  const double len_u = quad.edge_u.norm(), len_v = quad.edge_v.norm();
  const Eigen::Vector3d g_u = R_c_w * quad.edge_u / (len_u * tex.texel_size_m);
  const Eigen::Vector3d g_v = R_c_w * quad.edge_v / (len_v * tex.texel_size_m);
  const double s0 = g_u.dot(corners[0]), t0 = g_v.dot(corners[0]);
  const double s_max = len_u / tex.texel_size_m, t_max = len_v / tex.texel_size_m;
  const float inv_fx = static_cast<float>(1.0 / fx_);
  // Mip level: log2 of the pixel footprint in level-0 texels, taken as the
  // geometric mean of the two axes: (d / f / texel) * (|r| / |n.r|)^1.5, so
  // level = log2(d / f / texel) + 0.75 * log2(|r|^2 / (n.r)^2).
  const float lod_offset = static_cast<float>(std::log2(std::abs(d) / (std::sqrt(fx_ * fy_) * tex.texel_size_m)));
  const int top_level = std::min(static_cast<int>(tex.levels.size()), kMaxLevels) - 1;
  LevelView views[kMaxLevels];
  for (int l = 0; l <= top_level; ++l) {
    const cv::Mat& img = tex.levels[static_cast<std::size_t>(l)];
    views[l] = {img.ptr<std::uint8_t>(0), img.step[0], img.cols - 1, img.rows - 1, 256.0f / static_cast<float>(1 << l)};
  }
  const int shade_q = static_cast<int>(quad.shade * 256.0f + 0.5f);
  const float fd = static_cast<float>(d), fnear = static_cast<float>(options_.near_m);
  const float fs0 = static_cast<float>(s0), ft0 = static_cast<float>(t0);
  const float s_hi = static_cast<float>(s_max), t_hi = static_cast<float>(t_max);

  for (int y = y_first; y <= y_last; ++y) {
    // Span of the convex polygon on this row.
    double xl = 1e18, xr = -1e18;
    for (int i = 0; i < n; ++i) {
      const Vertex& a = poly[i];
      const Vertex& b = poly[(i + 1) % n];
      if ((a.y <= y && b.y >= y) || (b.y <= y && a.y >= y)) {
        if (std::abs(b.y - a.y) < 1e-12) {
          xl = std::min({xl, a.x, b.x});
          xr = std::max({xr, a.x, b.x});
        } else {
          const double x = a.x + (y - a.y) * (b.x - a.x) / (b.y - a.y);
          xl = std::min(xl, x);
          xr = std::max(xr, x);
        }
      }
    }
    const auto yi = static_cast<std::size_t>(y);
    const int x_first = std::max(row_begin_[yi], static_cast<int>(std::ceil(xl - 1e-3)));
    const int x_last = std::min(row_end_[yi] - 1, static_cast<int>(std::floor(xr + 1e-3)));
    if (x_first > x_last) continue;
    // Along the row every quantity is affine in x: value = a * x + b.
    const double ry = (y - cy_) / fy_;
    const auto affine_b = [&](const Eigen::Vector3d& g) {
      return static_cast<float>(g.y() * ry + g.z() - g.x() * cx_ / fx_);
    };
    const float na = static_cast<float>(normal.x()) * inv_fx, nb = affine_b(normal);
    const float ua = static_cast<float>(g_u.x()) * inv_fx, ub = affine_b(g_u);
    const float va = static_cast<float>(g_v.x()) * inv_fx, vb = affine_b(g_v);
    const float ry2 = static_cast<float>(ry * ry) + 1.0f;
    const float cxf = static_cast<float>(cx_);
    float* zrow = zbuffer_.ptr<float>(y);
    std::uint8_t* crow = canvas_.ptr<std::uint8_t>(y);
    for (int x = x_first; x <= x_last; ++x) {
      const float xf = static_cast<float>(x);
      const float nr = na * xf + nb;
      const float z = fd / nr;
      if (!(z < zrow[x]) || z < fnear) continue;  // hidden, behind, or parallel (inf/nan)
      float s = z * (ua * xf + ub) - fs0, t = z * (va * xf + vb) - ft0;
      if (s < -0.5f || t < -0.5f || s > s_hi + 0.5f || t > t_hi + 0.5f) continue;  // numerical slack at edges
      s = std::clamp(s, 0.0f, s_hi);
      t = std::clamp(t, 0.0f, t_hi);
      zrow[x] = z;
      const float rx = (xf - cxf) * inv_fx;
      const float lod = lod_offset + 0.75f * (fast_log2(rx * rx + ry2) - 2.0f * fast_log2(std::abs(nr)));
      const int level = lod > 0.0f ? std::min(static_cast<int>(lod), top_level) : 0;
      const LevelView& lv = views[level];
      // Texel coordinates in 1/256 units, shifted by +1 texel so that truncation
      // is floor (s - 0.5 >= -0.5). pyrDown puts texel i of level L over level-0
      // texel 2^L i, whose centre is at continuous coordinate 2^L i + 0.5.
      const int si = static_cast<int>((s - 0.5f) * lv.scale256 + 256.0f);
      const int ti = static_cast<int>((t - 0.5f) * lv.scale256 + 256.0f);
      const int ix = (si >> 8) - 1, iy = (ti >> 8) - 1, ax = si & 255, ay = ti & 255;
      const int x0 = std::clamp(ix, 0, lv.w1), x1 = std::clamp(ix + 1, 0, lv.w1);
      const std::uint8_t* r0 = lv.data + static_cast<std::size_t>(std::clamp(iy, 0, lv.h1)) * lv.step;
      const std::uint8_t* r1 = lv.data + static_cast<std::size_t>(std::clamp(iy + 1, 0, lv.h1)) * lv.step;
      const int top = (r0[x0] << 8) + ax * (r0[x1] - r0[x0]);
      const int bottom = (r1[x0] << 8) + ax * (r1[x1] - r1[x0]);
      const int value = ((top << 8) + ay * (bottom - top)) >> 8;  // grey * 256
      const int shaded = (value * shade_q + (1 << 15)) >> 16;
      crow[x] = static_cast<std::uint8_t>(shaded > 255 ? 255 : shaded);
    }
  }
}

}  // namespace orbatlas::sim
