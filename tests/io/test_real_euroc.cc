// Reading the real 95-frame EuRoC V1_01 clip of ../shared/data/euroc (optional).
#include <gtest/gtest.h>

#include <filesystem>

#include "core/common/data_paths.h"
#include "core/io/euroc_reader.h"
#include "tests/support/requirement.h"

namespace orbatlas {
namespace {

#define ORBATLAS_REQUIRE_REAL_EUROC(var)                                                   \
  const std::optional<std::filesystem::path> var = shared_euroc_dir();                     \
  if (!var || !std::filesystem::is_directory(*var / "V1_01_micro")) {                      \
    ORBATLAS_NEEDS("the real EuRoC data (../shared/data/euroc or ORBATLAS_SHARED_EUROC)"); \
  }

TEST(RealEuroc, ReadsV101Micro) {
  ORBATLAS_REQUIRE_REAL_EUROC(shared);
  const EurocDataset d = read_euroc_dataset(*shared / "V1_01_micro", {.require_cam1 = true, .require_imu = true});

  ASSERT_EQ(d.cameras.size(), 2u);
  EXPECT_EQ(d.cameras[0].frames.size(), 95u);
  EXPECT_EQ(d.cameras[1].frames.size(), 95u);  // 99 csv rows, 4 without an image
  ASSERT_EQ(d.warnings.size(), 4u);
  for (const auto& w : d.warnings) EXPECT_NE(w.find("cam1/data.csv"), std::string::npos) << w;
  EXPECT_EQ(d.cameras[0].frames.front().t_ns, 1403715273262142976);
  EXPECT_EQ(d.cameras[0].frames.back().t_ns, 1403715277962142976);

  const auto pairs = pair_stereo_frames(d);
  EXPECT_EQ(pairs.size(), 95u);

  const CameraCalibration& c0 = d.cameras[0].calibration;
  EXPECT_EQ(c0.model, CameraModel::kPinholeRadTan);
  EXPECT_DOUBLE_EQ(c0.fx, 458.654);
  EXPECT_DOUBLE_EQ(c0.fy, 457.296);
  EXPECT_DOUBLE_EQ(c0.cx, 367.215);
  EXPECT_DOUBLE_EQ(c0.cy, 248.375);
  ASSERT_EQ(c0.distortion.size(), 4u);
  EXPECT_DOUBLE_EQ(c0.distortion[0], -0.28340811);
  EXPECT_DOUBLE_EQ(c0.distortion[1], 0.07395907);
  EXPECT_DOUBLE_EQ(c0.distortion[2], 0.00019359);
  EXPECT_DOUBLE_EQ(c0.distortion[3], 1.76187114e-05);
  EXPECT_EQ(c0.width, 752);
  EXPECT_EQ(c0.height, 480);
  EXPECT_DOUBLE_EQ(c0.rate_hz, 20.0);
  // T_BS of cam0 (re-orthonormalised on reading: agrees to ~1e-9).
  Eigen::Matrix4d t_bs;
  t_bs << 0.0148655429818, -0.999880929698, 0.00414029679422, -0.0216401454975, 0.999557249008, 0.0149672133247,
      0.025715529948, -0.064676986768, -0.0257744366974, 0.00375618835797, 0.999660727178, 0.00981073058949, 0.0, 0.0,
      0.0, 1.0;
  EXPECT_LT((c0.T_b_c.matrix() - t_bs).cwiseAbs().maxCoeff(), 1e-8);
  EXPECT_DOUBLE_EQ(d.cameras[1].calibration.fx, 457.587);
  EXPECT_DOUBLE_EQ(d.cameras[1].calibration.T_b_c.t.y(), 0.0453689425024);

  ASSERT_TRUE(d.imu_calibration.has_value());
  EXPECT_DOUBLE_EQ(d.imu_calibration->rate_hz, 200.0);
  EXPECT_DOUBLE_EQ(d.imu_calibration->gyro_noise_density, 1.6968e-04);
  EXPECT_DOUBLE_EQ(d.imu_calibration->gyro_random_walk, 1.9393e-05);
  EXPECT_DOUBLE_EQ(d.imu_calibration->accel_noise_density, 2.0e-3);
  EXPECT_DOUBLE_EQ(d.imu_calibration->accel_random_walk, 3.0e-3);
  EXPECT_TRUE(d.imu_calibration->T_b_i.matrix().isIdentity(1e-12));

  ASSERT_EQ(d.imu.size(), 29120u);
  EXPECT_EQ(d.imu.front().t_ns, 1403715273262142976);
  EXPECT_EQ(d.imu.back().t_ns, 1403715418857143040);
  EXPECT_DOUBLE_EQ(d.imu.front().gyro.x(), -0.0020943951023931952);
  EXPECT_DOUBLE_EQ(d.imu.front().accel.z(), -3.6938381666666662);

  ASSERT_EQ(d.ground_truth.size(), 101u);
  EXPECT_DOUBLE_EQ(d.ground_truth.front().T_w_b.t.x(), 0.878895);
  EXPECT_NEAR(d.ground_truth.front().T_w_b.q.w(), 0.069433, 1e-5);
  EXPECT_DOUBLE_EQ(d.ground_truth.front().accel_bias.z(), 0.0309774);
}

}  // namespace
}  // namespace orbatlas
