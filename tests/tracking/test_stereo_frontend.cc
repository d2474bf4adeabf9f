// The stereo front end on a rendered Machine Hall pair and on bad input.
#include <gtest/gtest.h>

#include "core/camera/camera_factory.h"
#include "core/common/data_paths.h"
#include "core/common/error.h"
#include "core/io/settings.h"
#include "core/sim/euroc_sequences.h"
#include "core/sim/machine_hall.h"
#include "core/sim/renderer.h"
#include "core/sim/trajectory_spline.h"
#include "core/tracking/stereo_frontend.h"

namespace orbatlas {
namespace {

// A rendered Machine Hall pair (MH_01 at 40 s) and the cam0 renderer's world.
struct RenderedPair {
  sim::World world;
  std::unique_ptr<Camera> cam0, cam1;
  Pose3 T_w_c0;  // where cam0 was
  cv::Mat left, right;
};

RenderedPair render_pair(const SlamSettings& settings) {
  sim::MachineHallOptions hall;
  hall.texel_size_m = 0.01;  // quick to build
  RenderedPair p{sim::build_machine_hall(sim::load_machine_hall_trajectories(), hall),
                 make_camera(settings.camera0),
                 make_camera(*settings.camera1),
                 {},
                 {},
                 {}};
  const sim::TrajectorySpline spline(sim::load_ground_truth(sim::find_sequence("MH_01")));
  const Pose3 T_w_b = spline.pose(spline.start_ns() + 40 * kNsPerSecond);
  sim::RenderOptions ro;
  sim::Renderer r0(p.world, *p.cam0, ro), r1(p.world, *p.cam1, ro);
  p.T_w_c0 = T_w_b * settings.camera0.T_b_c;
  r0.render(p.T_w_c0, p.left, 1);
  r1.render(T_w_b * settings.camera1->T_b_c, p.right, 2);
  return p;
}

// Frame k of two front ends: the same keypoints, descriptors and stereo
// depths, most keypoints with depth.
void expect_same_frame(const Frame& a, const Frame& b, int k) {
  ASSERT_EQ(a.size(), b.size()) << "frame " << k;
  ASSERT_GT(a.stereo_count(), a.size() / 3);
  for (std::size_t i = 0; i < a.size(); ++i) {
    ASSERT_EQ(a.features.keypoints[i].uv, b.features.keypoints[i].uv);
    ASSERT_EQ(a.features.keypoints[i].angle_deg, b.features.keypoints[i].angle_deg);
    ASSERT_EQ(a.features.descriptors[i], b.features.descriptors[i]);
    ASSERT_EQ(a.depth[i], b.depth[i]) << "frame " << k << " keypoint " << i;
    ASSERT_EQ(a.u_right[i], b.u_right[i]);
  }
}

TEST(StereoFrontend, RenderedPairGivesKeypointsWithDepthConsistentWithTheScene) {
  const SlamSettings settings = read_settings(shipped_config_dir() / "euroc" / "stereo.yaml", SensorType::kStereo);
  const RenderedPair pair = render_pair(settings);
  sim::Renderer r0(pair.world, *pair.cam0, sim::RenderOptions{});
  cv::Mat rendered;
  r0.render(pair.T_w_c0, rendered, 1);  // the left image again, for its depth buffer
  const cv::Mat &left = pair.left, &right = pair.right;

  StereoFrontend frontend(settings);
  const Frame f = frontend.make_frame(123, left, right);
  EXPECT_EQ(f.t_ns, 123);
  EXPECT_GE(f.size(), 1150u);
  EXPECT_GT(f.stereo_count(), f.size() / 3);
  ASSERT_EQ(f.depth.size(), f.size());
  ASSERT_EQ(f.map_points.size(), f.size());
  EXPECT_EQ(f.grid.size(), f.size());
  // Depths agree with the renderer's depth buffer: the point at a keypoint's
  // stereo depth along its ray, seen from cam0, has the depth cam0 rendered there.
  const Pose3 T_c0_rect = settings.camera0.T_b_c.inverse() * frontend.calibration().T_b_c;
  std::vector<double> rel;
  for (std::size_t i = 0; i < f.size(); ++i) {
    if (f.depth[i] <= 0) continue;
    const Eigen::Vector3d& b = f.features.keypoints[i].bearing;
    const Eigen::Vector3d p_c0 = T_c0_rect * (b * (f.depth[i] / b.z()));
    const auto truth = r0.depth_along(p_c0);
    if (truth) rel.push_back(std::abs(p_c0.z() - *truth) / *truth);
  }
  ASSERT_GT(rel.size(), 300u);
  std::nth_element(rel.begin(), rel.begin() + static_cast<std::ptrdiff_t>(rel.size() / 2), rel.end());
  EXPECT_LT(rel[rel.size() / 2], 0.01);
}

// The right image on the second thread, or taken back by the caller's thread
// when the worker has not started it: the same frame either way, as a serial
// front end makes it; every pair is counted, and a serial one never uses a worker.
TEST(StereoFrontend, ParallelAndSerialFrontEndsMakeTheSameFrames) {
  const SlamSettings settings = read_settings(shipped_config_dir() / "euroc" / "stereo.yaml", SensorType::kStereo);
  const RenderedPair pair = render_pair(settings);
  StereoFrontend parallel(settings, true), serial(settings, false);
  constexpr int kFrames = 30;
  for (int k = 0; k < kFrames; ++k) {
    const Frame a = parallel.make_frame(k + 1, pair.left, pair.right);
    const Frame b = serial.make_frame(k + 1, pair.left, pair.right);
    ASSERT_NO_FATAL_FAILURE(expect_same_frame(a, b, k));
  }
  EXPECT_EQ(parallel.stereo_frames(), static_cast<std::size_t>(kFrames));
  EXPECT_LE(parallel.right_images_on_worker(), static_cast<std::size_t>(kFrames));
  EXPECT_EQ(serial.stereo_frames(), static_cast<std::size_t>(kFrames));
  EXPECT_EQ(serial.right_images_on_worker(), 0u);
}

// The warm-up before a session's first frame (a textured pair of the
// calibrated size through the front end) changes no frame made afterwards and
// is not counted as a stereo pair.
TEST(StereoFrontend, WarmUpChangesNoFrameAndIsNotCounted) {
  const SlamSettings settings = read_settings(shipped_config_dir() / "euroc" / "stereo.yaml", SensorType::kStereo);
  const RenderedPair pair = render_pair(settings);
  StereoFrontend warm(settings, true), cold(settings, true);
  warm.warm_up();
  EXPECT_EQ(warm.stereo_frames(), 0u);
  EXPECT_EQ(warm.right_images_on_worker(), 0u);
  for (int k = 0; k < 3; ++k) {
    const Frame a = warm.make_frame(k + 1, pair.left, pair.right);
    const Frame b = cold.make_frame(k + 1, pair.left, pair.right);
    ASSERT_NO_FATAL_FAILURE(expect_same_frame(a, b, k));
  }
  EXPECT_EQ(warm.stereo_frames(), 3u);
}

TEST(StereoFrontend, RejectsBadImages) {
  const SlamSettings settings = read_settings(shipped_config_dir() / "euroc" / "stereo.yaml", SensorType::kStereo);
  StereoFrontend frontend(settings);
  const cv::Mat ok(480, 752, CV_8UC1, cv::Scalar(100)), small(240, 376, CV_8UC1, cv::Scalar(100)), empty;
  const cv::Mat wide(480, 752, CV_16UC1, cv::Scalar(100));
  EXPECT_THROW(frontend.make_frame(0, empty, ok), Error);
  EXPECT_THROW(frontend.make_frame(0, ok, small), Error);
  EXPECT_THROW(frontend.make_frame(0, wide, ok), Error);
  const Frame blank = frontend.make_frame(0, ok, ok);  // no texture: no crash, few or no features
  EXPECT_EQ(blank.depth.size(), blank.size());
  const SlamSettings mono = read_settings(shipped_config_dir() / "euroc" / "mono.yaml", SensorType::kMonocular);
  EXPECT_THROW(StereoFrontend{mono}, Error);
}

}  // namespace
}  // namespace orbatlas
