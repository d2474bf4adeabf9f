#include "core/features/stereo_triangulated.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/video/tracking.hpp>

#include "core/common/error.h"

namespace orbatlas {

void TriangulatedStereoOptions::check() const {
  ORBATLAS_CHECK(max_hamming >= 0, "triangulated stereo: max_hamming must be >= 0, not " << max_hamming);
  ORBATLAS_CHECK(ratio >= 0.0 && ratio <= 1.0, "triangulated stereo: ratio must be in [0, 1], not " << ratio);
  ORBATLAS_CHECK(max_reprojection_sigma2 > 0.0,
                 "triangulated stereo: max_reprojection_sigma2 must be > 0, not " << max_reprojection_sigma2);
  ORBATLAS_CHECK(min_parallax_deg >= 0.0 && min_parallax_deg <= 180.0,
                 "triangulated stereo: min_parallax_deg must be in [0, 180], not " << min_parallax_deg);
  // cv::calcOpticalFlowPyrLK needs a window of at least 3x3.
  ORBATLAS_CHECK(sad_half_window >= 1, "triangulated stereo: sad_half_window must be >= 1, not " << sad_half_window);
}

bool triangulate_rays(const Eigen::Vector3d& o1, const Eigen::Vector3d& d1, const Eigen::Vector3d& o2,
                      const Eigen::Vector3d& d2, Eigen::Vector3d* point) {
  // Minimise |o1 + s d1 - (o2 + t d2)|^2 over s, t.
  const Eigen::Vector3d w = o1 - o2;
  const double b = d1.dot(d2), d = d1.dot(w), e = d2.dot(w);
  const double denom = 1.0 - b * b;
  if (denom < 1e-12) return false;
  const double s = (b * e - d) / denom, t = (e - b * d) / denom;
  if (s <= 0.0 || t <= 0.0) return false;
  *point = 0.5 * ((o1 + s * d1) + (o2 + t * d2));
  return true;
}

std::size_t TriangulatedStereo::matched() const {
  return static_cast<std::size_t>(std::count_if(right_index.begin(), right_index.end(), [](int i) { return i >= 0; }));
}

namespace {

struct Candidate {
  std::size_t left;
  std::size_t right;
  int distance;
};

// Best right keypoint per left keypoint by descriptor, with the ratio test; a
// right keypoint claimed twice keeps the closer descriptor.
std::vector<Candidate> descriptor_candidates(const ImageFeatures& left, const ImageFeatures& right,
                                             const TriangulatedStereoOptions& options) {
  std::vector<int> owner(right.keypoints.size(), -1);
  std::vector<Candidate> out;
  for (std::size_t il = 0; il < left.keypoints.size(); ++il) {
    int best = std::numeric_limits<int>::max(), second = best;
    std::size_t best_ir = 0;
    for (std::size_t ir = 0; ir < right.keypoints.size(); ++ir) {
      const int d = hamming(left.descriptors[il], right.descriptors[ir]);
      if (d < best) {
        second = best;
        best = d;
        best_ir = ir;
      } else if (d < second) {
        second = d;
      }
    }
    if (best > options.max_hamming || static_cast<double>(best) > options.ratio * second) continue;
    if (owner[best_ir] >= 0) {
      Candidate& other = out[static_cast<std::size_t>(owner[best_ir])];
      if (other.distance <= best) continue;
      other = {il, best_ir, best};
      continue;
    }
    owner[best_ir] = static_cast<int>(out.size());
    out.push_back({il, best_ir, best});
  }
  return out;
}

}  // namespace

TriangulatedStereo match_stereo_triangulated(const Camera& left_camera, const ImageFeatures& left,
                                             const Camera& right_camera, const ImageFeatures& right, const Pose3& T_l_r,
                                             const std::vector<double>& level_sigma2, const cv::Mat& left_image,
                                             const cv::Mat& right_image, const TriangulatedStereoOptions& options) {
  const std::size_t n = left.keypoints.size();
  TriangulatedStereo out;
  out.right_index.assign(n, -1);
  out.depth.assign(n, -1.0f);
  out.points_left.assign(n, Eigen::Vector3d::Zero());
  const std::vector<Candidate> candidates = descriptor_candidates(left, right, options);
  if (candidates.empty()) return out;

  // Observations used for triangulation: the keypoints, or with images the right
  // positions re-found to sub-pixel by Lucas-Kanade from the left keypoints (the
  // keypoints themselves are quantised to their level's grid, up to 2 px).
  std::vector<cv::Point2f> pts_l, pts_r;
  for (const Candidate& c : candidates) {
    pts_l.emplace_back(left.keypoints[c.left].uv.x(), left.keypoints[c.left].uv.y());
    pts_r.emplace_back(right.keypoints[c.right].uv.x(), right.keypoints[c.right].uv.y());
  }
  std::vector<unsigned char> ok(candidates.size(), 1);
  if (!left_image.empty() && !right_image.empty()) {
    std::vector<float> err;
    const std::vector<cv::Point2f> initial = pts_r;
    const int win = 2 * options.sad_half_window + 1;
    cv::calcOpticalFlowPyrLK(left_image, right_image, pts_l, pts_r, ok, err, cv::Size(win, win), 1,
                             cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 30, 0.001),
                             cv::OPTFLOW_USE_INITIAL_FLOW);
    for (std::size_t k = 0; k < candidates.size(); ++k) {
      // The refinement may only polish the match, not move it to another place.
      const float limit =
          1.0f + static_cast<float>(
                     std::sqrt(level_sigma2[static_cast<std::size_t>(right.keypoints[candidates[k].right].level)]));
      if (ok[k] && cv::norm(pts_r[k] - initial[k]) > limit) ok[k] = 0;
    }
  }

  const Pose3 T_r_l = T_l_r.inverse();
  const double cos_min_parallax = std::cos(options.min_parallax_deg * M_PI / 180.0);
  for (std::size_t k = 0; k < candidates.size(); ++k) {
    if (!ok[k]) continue;
    const Keypoint& kl = left.keypoints[candidates[k].left];
    const Keypoint& kr = right.keypoints[candidates[k].right];
    const Eigen::Vector2d obs_l(pts_l[k].x, pts_l[k].y), obs_r(pts_r[k].x, pts_r[k].y);
    const Eigen::Vector3d ray_l = left_camera.unproject(obs_l);
    const Eigen::Vector3d d_r_in_l = T_l_r.q * right_camera.unproject(obs_r);
    if (ray_l.dot(d_r_in_l) > cos_min_parallax) continue;  // too little parallax
    Eigen::Vector3d p_l;
    if (!triangulate_rays(Eigen::Vector3d::Zero(), ray_l, T_l_r.t, d_r_in_l, &p_l)) continue;
    // Reprojection in both images, in units of each level's sigma^2.
    Eigen::Vector2d uv_l, uv_r;
    if (!left_camera.project(p_l, &uv_l) || !right_camera.project(T_r_l * p_l, &uv_r)) continue;
    const double e_l = (uv_l - obs_l).squaredNorm() / level_sigma2[static_cast<std::size_t>(kl.level)];
    const double e_r = (uv_r - obs_r).squaredNorm() / level_sigma2[static_cast<std::size_t>(kr.level)];
    if (e_l > options.max_reprojection_sigma2 || e_r > options.max_reprojection_sigma2) continue;
    out.right_index[candidates[k].left] = static_cast<int>(candidates[k].right);
    out.depth[candidates[k].left] = static_cast<float>(p_l.z());
    out.points_left[candidates[k].left] = p_l;
  }
  return out;
}

}  // namespace orbatlas
