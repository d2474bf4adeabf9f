#pragma once
// Exact synthetic ground truth for the Sim3 tests: random similarities and
// their perturbations, a tolerance check, and scenes of matches between two
// cameras related by a known Sim3 (with outliers and noise on request), with
// the share of outliers an estimator flagged and of inliers it kept.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <utility>
#include <vector>

#include "core/camera/camera.h"
#include "core/geometry/sim3.h"
#include "core/geometry/so3.h"
#include "core/optimization/level_sigma.h"
#include "core/optimization/sim3_match.h"

namespace orbatlas::test {

inline constexpr double kDegree = M_PI / 180.0;

inline Eigen::Vector3d gaussian3(std::mt19937& rng, double sigma = 1.0) {
  std::normal_distribution<double> n(0.0, sigma);
  return Eigen::Vector3d(n(rng), n(rng), n(rng));
}

inline Sim3 random_sim3(std::mt19937& rng, double angle_rad, double meters, double scale) {
  const Eigen::Vector3d axis = gaussian3(rng).normalized();
  return Sim3(so3_exp(axis * angle_rad), gaussian3(rng).normalized() * meters, scale);
}

// `S` moved by `angle_rad`, `meters` and a scale factor.
inline Sim3 perturb(const Sim3& S, double angle_rad, double meters, double scale_factor, std::mt19937& rng) {
  return Sim3(so3_exp(gaussian3(rng).normalized() * angle_rad) * S.q, S.t + gaussian3(rng).normalized() * meters,
              S.s * scale_factor);
}

inline void expect_sim3_near(const Sim3& a, const Sim3& b, double rad, double meters, double log_scale) {
  EXPECT_LE(sim3_rotation_distance(a, b), rad);
  EXPECT_LE((a.t - b.t).norm(), meters);
  EXPECT_LE(sim3_log_scale_distance(a, b), log_scale);
}

struct Sim3Scene {
  Sim3 S_1_2;
  std::vector<Sim3Match> matches;
  std::vector<std::uint8_t> is_outlier;
};

struct SceneOptions {
  int matches = 200;
  double scale = 1.0;             // true scale of S_1_2
  double outlier_fraction = 0.0;  // wrong matches (another point's data on side 2)
  double pixel_noise = 0.0;       // keypoint noise, times the level's sigma
  // Relative noise of each point's distance along its ray: a triangulated or stereo
  // depth is far less certain than the direction of its keypoint.
  double depth_noise = 0.0;
};

// Points in front of camera 1 (1.5-10 m), visible in camera 2; S_1_2 ~15 deg and
// 0.4 m (in camera-1 units) away from the identity.
inline Sim3Scene make_scene(const Camera& cam1, const Camera& cam2, const SceneOptions& so, std::mt19937& rng) {
  Sim3Scene s;
  s.S_1_2 = random_sim3(rng, 15.0 * kDegree, 0.4, so.scale);
  const Sim3 S_2_1 = s.S_1_2.inverse();
  const std::vector<double> sigma2 = pyramid_level_sigma2();
  std::uniform_real_distribution<double> u(20.0, cam1.width() - 20.0), v(20.0, cam1.height() - 20.0);
  std::uniform_real_distribution<double> range(1.5, 10.0), unit(0.0, 1.0);
  std::uniform_int_distribution<int> level(0, 7);
  std::normal_distribution<double> noise(0.0, 1.0);

  // A point seen by both cameras: (p_c1, uv1, p_c2, uv2), exact.
  auto draw = [&](Eigen::Vector3d* p_c1, Eigen::Vector2d* uv1, Eigen::Vector3d* p_c2, Eigen::Vector2d* uv2) {
    while (true) {
      *p_c1 = cam1.unproject(Eigen::Vector2d(u(rng), v(rng))) * range(rng);
      *p_c2 = S_2_1 * *p_c1;
      if (cam1.project(*p_c1, uv1) && cam2.project(*p_c2, uv2) && cam2.in_image(*uv2, 10.0)) return;
    }
  };
  while (static_cast<int>(s.matches.size()) < so.matches) {
    Sim3Match m;
    draw(&m.p_c1, &m.uv1, &m.p_c2, &m.uv2);
    m.level_sigma2_1 = sigma2[static_cast<std::size_t>(level(rng))];
    m.level_sigma2_2 = sigma2[static_cast<std::size_t>(level(rng))];
    const bool outlier = unit(rng) < so.outlier_fraction;
    if (outlier) {
      // Side 2 belongs to another point, far from this one in image 1.
      Eigen::Vector3d q1, q2;
      Eigen::Vector2d w1, w2;
      do draw(&q1, &w1, &q2, &w2);
      while ((w1 - m.uv1).norm() < 30.0);
      m.p_c2 = q2;
      m.uv2 = w2;
    }
    m.p_c1 *= 1.0 + so.depth_noise * noise(rng);
    m.p_c2 *= 1.0 + so.depth_noise * noise(rng);
    m.uv1 += Eigen::Vector2d(noise(rng), noise(rng)) * so.pixel_noise * std::sqrt(m.level_sigma2_1);
    m.uv2 += Eigen::Vector2d(noise(rng), noise(rng)) * so.pixel_noise * std::sqrt(m.level_sigma2_2);
    s.matches.push_back(m);
    s.is_outlier.push_back(outlier ? 1 : 0);
  }
  return s;
}

inline int count(const std::vector<std::uint8_t>& flags) {
  int n = 0;
  for (std::uint8_t f : flags) n += f;
  return n;
}

// Outliers flagged (recall) and inliers kept, in percent.
inline std::pair<double, double> classification(const std::vector<std::uint8_t>& inliers,
                                                const std::vector<std::uint8_t>& is_outlier) {
  int outliers = 0, flagged = 0, good = 0, kept = 0;
  for (std::size_t i = 0; i < inliers.size(); ++i) {
    if (is_outlier[i]) {
      ++outliers;
      flagged += inliers[i] ? 0 : 1;
    } else {
      ++good;
      kept += inliers[i];
    }
  }
  return {outliers ? 100.0 * flagged / outliers : 100.0, good ? 100.0 * kept / good : 100.0};
}

}  // namespace orbatlas::test
