#include "core/features/stereo_rectified.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "core/common/error.h"
#include "core/features/patch_sad.h"
#include "core/features/remap_bilinear.h"

namespace orbatlas {
namespace {

cv::Mat intrinsics(const CameraCalibration& c) {
  return (cv::Mat_<double>(3, 3) << c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1);
}

cv::Mat to_cv(const Eigen::Matrix3d& m) {
  cv::Mat out(3, 3, CV_64F);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) out.at<double>(i, j) = m(i, j);
  return out;
}

Eigen::Matrix3d from_cv3(const cv::Mat& m) {
  Eigen::Matrix3d out;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) out(i, j) = m.at<double>(i, j);
  return out;
}

}  // namespace

StereoRectifier::StereoRectifier(const CameraCalibration& left, const CameraCalibration& right) {
  ORBATLAS_CHECK(left.model == CameraModel::kPinholeRadTan && right.model == CameraModel::kPinholeRadTan,
                 "stereo rectification needs two pinhole cameras; use triangulated stereo for fisheye rigs");
  ORBATLAS_CHECK(left.width == right.width && left.height == right.height, "stereo cameras differ in image size");
  const Pose3 T_c1_c0 = right.T_b_c.inverse() * left.T_b_c;  // left camera in the right camera's frame
  const cv::Size size(left.width, left.height);
  cv::Mat R1, R2, P1, P2, Q;
  const cv::Mat T = (cv::Mat_<double>(3, 1) << T_c1_c0.t.x(), T_c1_c0.t.y(), T_c1_c0.t.z());
  cv::stereoRectify(intrinsics(left), cv::Mat(left.distortion), intrinsics(right), cv::Mat(right.distortion), size,
                    to_cv(T_c1_c0.rotation()), T, R1, R2, P1, P2, Q, cv::CALIB_ZERO_DISPARITY, 0);
  cv::Mat map_x, map_y;
  cv::initUndistortRectifyMap(intrinsics(left), cv::Mat(left.distortion), R1, P1, size, CV_32F, map_x, map_y);
  cv::convertMaps(map_x, map_y, map_left_xy_, map_left_frac_, CV_16SC2);
  cv::initUndistortRectifyMap(intrinsics(right), cv::Mat(right.distortion), R2, P2, size, CV_32F, map_x, map_y);
  cv::convertMaps(map_x, map_y, map_right_xy_, map_right_frac_, CV_16SC2);
  size_ = size;
  baseline_ = -P2.at<double>(0, 3) / P2.at<double>(0, 0);
  ORBATLAS_CHECK(baseline_ > 0.0, "stereo rectification: the right camera is not to the right of the left one");

  auto rectified = [&](const CameraCalibration& in, const cv::Mat& R) {
    CameraCalibration c = in;
    c.fx = P1.at<double>(0, 0);
    c.fy = P1.at<double>(1, 1);
    c.cx = P1.at<double>(0, 2);
    c.cy = P1.at<double>(1, 2);
    c.distortion = {0.0, 0.0, 0.0, 0.0};
    // R maps the original camera frame to the rectified one: p_rect = R p_orig.
    const Pose3 T_orig_rect(Eigen::Quaterniond(from_cv3(R).transpose()), Eigen::Vector3d::Zero());
    c.T_b_c = in.T_b_c * T_orig_rect;
    return c;
  };
  rect_left_ = rectified(left, R1);
  rect_right_ = rectified(right, R2);
}

void StereoRectifier::rectify(const cv::Mat& left, const cv::Mat& right, cv::Mat& left_rect,
                              cv::Mat& right_rect) const {
  ORBATLAS_CHECK(left.size() == size_ && right.size() == size_,
                 "stereo images of " << left.cols << "x" << left.rows << " and " << right.cols << "x" << right.rows
                                     << " do not match the calibration (" << size_.width << "x" << size_.height << ")");
  remap_bilinear(left, left_rect, map_left_xy_, map_left_frac_);
  remap_bilinear(right, right_rect, map_right_xy_, map_right_frac_);
}

void StereoRectifier::rectify_left(const cv::Mat& left, cv::Mat& left_rect) const {
  ORBATLAS_CHECK(left.size() == size_,
                 "left image of " << left.cols << "x" << left.rows << " does not match the calibration");
  remap_bilinear(left, left_rect, map_left_xy_, map_left_frac_);
}

void StereoRectifier::rectify_right(const cv::Mat& right, cv::Mat& right_rect) const {
  ORBATLAS_CHECK(right.size() == size_,
                 "right image of " << right.cols << "x" << right.rows << " does not match the calibration");
  remap_bilinear(right, right_rect, map_right_xy_, map_right_frac_);
}

std::size_t StereoDepths::matched() const {
  return static_cast<std::size_t>(std::count_if(depth.begin(), depth.end(), [](float d) { return d > 0.0f; }));
}

void StereoMatchOptions::check() const {
  ORBATLAS_CHECK(max_hamming >= 0, "stereo matching: max_hamming must be >= 0, not " << max_hamming);
  // A one-pixel zero-mean SAD is always 0: no disparity could be refined.
  ORBATLAS_CHECK(sad_half_window >= 1, "stereo matching: sad_half_window must be >= 1, not " << sad_half_window);
  ORBATLAS_CHECK(sad_search >= 0, "stereo matching: sad_search must be >= 0, not " << sad_search);
  ORBATLAS_CHECK(std::isfinite(min_depth_baselines) && min_depth_baselines > 0.0,
                 "stereo matching: min_depth_baselines must be a finite value > 0, not " << min_depth_baselines);
  ORBATLAS_CHECK(outlier_factor > 0.0, "stereo matching: outlier_factor must be > 0, not " << outlier_factor);
}

StereoDepths match_stereo_rectified(const ImageFeatures& left, const std::vector<cv::Mat>& left_pyramid,
                                    const ImageFeatures& right, const std::vector<cv::Mat>& right_pyramid,
                                    const std::vector<double>& scale_factors, double bf, double baseline,
                                    const StereoMatchOptions& options) {
  const std::size_t n = left.keypoints.size();
  StereoDepths out;
  out.u_right.assign(n, -1.0f);
  out.depth.assign(n, -1.0f);
  if (n == 0 || right.keypoints.empty()) return out;
  ORBATLAS_CHECK(!scale_factors.empty() && left_pyramid.size() >= scale_factors.size() &&
                     right_pyramid.size() >= scale_factors.size(),
                 "stereo matching: pyramids and scale factors do not agree");

  // Right keypoints by the first row of the band they may match (+-2 sigma of
  // their level): those of first row y are [by_first[y], by_first[y + 1]) in
  // `right_rows`, each with its band's last row and what the search checks
  // before a descriptor. A left keypoint on row v looks at first rows
  // v - widest .. v (one pass over few, in memory order).
  const int rows = right.height > 0 ? right.height : right_pyramid[0].rows;
  struct RowCandidate {
    int last_row;
    float u;
    int level;
    std::uint32_t index;
  };
  const auto band = [&](const Keypoint& kp) {
    const float r = 2.0f * static_cast<float>(scale_factors[static_cast<std::size_t>(kp.level)]);
    return std::pair(std::max(0, static_cast<int>(std::floor(kp.uv.y() - r))),
                     std::min(rows - 1, static_cast<int>(std::ceil(kp.uv.y() + r))));
  };
  std::vector<std::uint32_t> by_first(static_cast<std::size_t>(rows) + 1, 0);
  int widest = 0;
  for (const Keypoint& kp : right.keypoints) {
    const auto [lo, hi] = band(kp);
    if (lo > hi) continue;  // outside the image's rows
    ++by_first[static_cast<std::size_t>(lo) + 1];
    widest = std::max(widest, hi - lo);
  }
  for (std::size_t y = 0; y < static_cast<std::size_t>(rows); ++y) by_first[y + 1] += by_first[y];
  std::vector<RowCandidate> right_rows(by_first.back());
  {
    std::vector<std::uint32_t> fill(by_first.begin(), by_first.end() - 1);
    for (std::uint32_t i = 0; i < right.keypoints.size(); ++i) {
      const Keypoint& kp = right.keypoints[i];
      const auto [lo, hi] = band(kp);
      if (lo > hi) continue;
      right_rows[fill[static_cast<std::size_t>(lo)]++] = {hi, kp.uv.x(), kp.level, i};
    }
  }

  const float min_disparity = 0.0f;
  const float max_disparity = static_cast<float>(bf / (options.min_depth_baselines * baseline));
  const int w = options.sad_half_window, search = options.sad_search;
  std::vector<std::pair<int, std::size_t>> costs;  // (SAD, left index)
  costs.reserve(n);
  std::vector<int> sad;
  RowSadSearch row_search;

  for (std::size_t il = 0; il < n; ++il) {
    const Keypoint& kl = left.keypoints[il];
    const int row = static_cast<int>(std::lround(kl.uv.y()));
    if (row < 0 || row >= rows) continue;
    const std::uint32_t begin = by_first[static_cast<std::size_t>(std::max(0, row - widest))];
    const std::uint32_t end = by_first[static_cast<std::size_t>(row) + 1];
    const float u_min = kl.uv.x() - max_disparity, u_max = kl.uv.x() - min_disparity;
    int best = options.max_hamming + 1;
    std::size_t best_ir = 0;
    const Descriptor& dl = left.descriptors[il];
    for (std::uint32_t c = begin; c < end; ++c) {
      const RowCandidate& kr = right_rows[c];
      if (kr.last_row < row) continue;  // its band ends above this row
      if (kr.level < kl.level - 1 || kr.level > kl.level + 1) continue;
      if (kr.u < u_min || kr.u > u_max) continue;
      // The least distance, and of equals the first keypoint (the order does not matter).
      const int d = hamming(dl, right.descriptors[kr.index]);
      if (d < best || (d == best && kr.index < best_ir)) {
        best = d;
        best_ir = kr.index;
      }
    }
    if (best > options.max_hamming) continue;

    // Sub-pixel refinement by SAD on the full-resolution images (finer than the
    // keypoint's level), searching around the descriptor match by the level's
    // quantisation plus options.sad_search pixels; an equiangular (V-shaped) fit
    // suits SAD costs better than a parabola, which pulls towards whole pixels.
    const auto level = static_cast<std::size_t>(kl.level);
    const cv::Mat& il_img = left_pyramid[0];
    const cv::Mat& ir_img = right_pyramid[0];
    const int ul = static_cast<int>(std::lround(kl.uv.x()));
    const int vl = static_cast<int>(std::lround(kl.uv.y()));
    const int ur0 = static_cast<int>(std::lround(right.keypoints[best_ir].uv.x()));
    const int range = search + static_cast<int>(std::ceil(scale_factors[level]));
    if (vl - w < 0 || vl + w >= il_img.rows || ul - w < 0 || ul + w >= il_img.cols) continue;
    if (ur0 - range - w < 0 || ur0 + range + w >= ir_img.cols || vl + w >= ir_img.rows) continue;
    row_search.run(il_img, ul, vl, ir_img, ur0, range, w, sad);
    int best_sad = std::numeric_limits<int>::max(), best_inc = 0;
    for (int inc = -range; inc <= range; ++inc) {
      const int s = sad[static_cast<std::size_t>(inc + range)];
      if (s < best_sad) {
        best_sad = s;
        best_inc = inc;
      }
    }
    if (best_inc == -range || best_inc == range) continue;  // minimum at the border: no fit
    const double s1 = sad[static_cast<std::size_t>(best_inc + range - 1)];
    const double s2 = sad[static_cast<std::size_t>(best_inc + range)];
    const double s3 = sad[static_cast<std::size_t>(best_inc + range + 1)];
    const double rise = std::max(s1, s3) - s2;
    if (rise <= 0.0) continue;  // flat cost: no texture along the row
    const double delta = 0.5 * (s1 - s3) / rise;
    // The patch is centred on the keypoint's whole pixel: its disparity is the
    // keypoint's, and the right coordinate is the keypoint's own less it (a
    // keypoint of a coarser level sits between pixels; its rounding is not
    // carried into the right coordinate the bundle adjustments use).
    double disparity = ul - (ur0 + best_inc + delta);
    if (disparity < min_disparity || disparity >= max_disparity) continue;
    if (disparity <= 0.0) disparity = 0.01;
    out.depth[il] = static_cast<float>(bf / disparity);
    out.u_right[il] = static_cast<float>(kl.uv.x() - disparity);
    costs.emplace_back(best_sad, il);
  }

  // Outliers: SAD cost far above the median.
  if (!costs.empty()) {
    std::vector<int> sorted(costs.size());
    std::transform(costs.begin(), costs.end(), sorted.begin(), [](const auto& c) { return c.first; });
    std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2), sorted.end());
    const double threshold = options.outlier_factor * sorted[sorted.size() / 2];
    for (const auto& [cost, il] : costs)
      if (cost > threshold) {
        out.depth[il] = -1.0f;
        out.u_right[il] = -1.0f;
      }
  }
  return out;
}

}  // namespace orbatlas
