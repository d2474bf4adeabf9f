// End to end: `orbatlas sim` writes a dataset that orbatlas' EuRoC reader reads
// back whole, consistent with the real trajectory; bad options are clear errors.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>

#include "core/common/error.h"
#include "core/io/euroc_reader.h"
#include "core/sim/euroc_sequences.h"
#include "core/sim/sequence_simulator.h"

namespace orbatlas {
namespace {

std::filesystem::path fresh_dir(const std::string& name) {
  const auto dir =
      std::filesystem::temp_directory_path() / ("orbatlas_test_sim_" + std::to_string(::getpid()) + "_" + name);
  std::filesystem::remove_all(dir);
  return dir;
}

TEST(SequenceSimulator, WritesAReadableEurocDataset) {
  sim::SimulationOptions o;
  o.sequence = "MH_02";
  o.out_dir = fresh_dir("mh02");
  o.start_s = 5.0;
  o.duration_s = 1.0;
  o.show_progress = false;
  const sim::SimulationReport r = sim::simulate_sequence(o);
  EXPECT_EQ(r.frames, 21u);  // 20 Hz, both ends included

  EurocReadOptions ro;
  ro.require_cam1 = true;
  ro.require_imu = true;
  const EurocDataset ds = read_euroc_dataset(o.out_dir, ro);
  ASSERT_EQ(ds.cameras.size(), 2u);
  EXPECT_EQ(ds.cameras[0].frames.size(), 21u);
  EXPECT_EQ(pair_stereo_frames(ds).size(), 21u);
  EXPECT_TRUE(ds.warnings.empty());
  EXPECT_NEAR(ds.cameras[0].calibration.fx, 458.654, 1e-9);
  EXPECT_NEAR((ds.cameras[1].calibration.T_b_c.t - ds.cameras[0].calibration.T_b_c.t).norm(), 0.110, 0.001);
  // IMU from 1 s before the first frame, 200 Hz, on the camera trigger grid.
  ASSERT_GT(ds.imu.size(), 390u);
  EXPECT_EQ((ds.cameras[0].frames.front().t_ns - ds.imu.front().t_ns) % 5'000'000, 0);
  // Ground truth follows the real trajectory within the smoothing.
  const Trajectory real = sim::load_ground_truth(sim::find_sequence("MH_02"));
  ASSERT_FALSE(ds.ground_truth.empty());
  for (std::size_t i = 0; i < ds.ground_truth.size(); i += 40) {
    const auto p = pose_at(real, ds.ground_truth[i].t_ns, kNsPerSecond / 10);
    ASSERT_TRUE(p.has_value());
    EXPECT_LT((p->t - ds.ground_truth[i].T_w_b.t).norm(), 0.02);
  }
  // Refuses to overwrite.
  EXPECT_THROW(sim::simulate_sequence(o), Error);
  std::filesystem::remove_all(o.out_dir);
}

TEST(SequenceSimulator, BadOptionsAreClearErrors) {
  sim::SimulationOptions o;
  o.out_dir = fresh_dir("bad");
  o.show_progress = false;
  o.sequence = "MH_09";
  EXPECT_THROW(sim::simulate_sequence(o), Error);
  o.sequence = "MH_02";
  o.imu = sim::ImuSource::kReal;
  try {
    sim::simulate_sequence(o);
    FAIL() << "--imu real is MH_01 and MH_05 only";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("MH_05"), std::string::npos) << e.what();
  }
  o.imu = sim::ImuSource::kSynthetic;
  o.start_s = 1e6;  // past the end
  EXPECT_THROW(sim::simulate_sequence(o), Error);
  EXPECT_FALSE(std::filesystem::exists(o.out_dir / "mav0")) << "nothing written on a rejected request";
}

TEST(SequenceSimulator, RealMh05ImuIsUsedVerbatim) {
  sim::SimulationOptions o;
  o.sequence = "MH_05";
  o.imu = sim::ImuSource::kReal;
  o.out_dir = fresh_dir("mh05");
  o.start_s = 20.0;
  o.duration_s = 0.2;
  o.show_progress = false;
  sim::simulate_sequence(o);
  const EurocDataset ds = read_euroc_dataset(o.out_dir);
  ASSERT_GT(ds.imu.size(), 200u);
  // The real IMU sees gravity mostly along its x axis at rest-like motion: |a| ~ 9.8.
  double mean_norm = 0;
  for (const auto& s : ds.imu) mean_norm += s.accel.norm() / static_cast<double>(ds.imu.size());
  EXPECT_NEAR(mean_norm, 9.8, 1.0);
  std::filesystem::remove_all(o.out_dir);
}

// The real MH_01 IMU (the lossy copy) as recorded, shifted by a clock offset
// when one is asked for; a variant's images are the first rendering's, linked.
TEST(SequenceSimulator, RealMh01ImuAndAVariantSharingTheImages) {
  sim::SimulationOptions o;
  o.sequence = "MH_01";
  o.imu = sim::ImuSource::kReal;
  o.out_dir = fresh_dir("mh01_real_imu");
  o.start_s = 60.0;
  o.duration_s = 0.2;
  o.show_progress = false;
  sim::simulate_sequence(o);
  const EurocDataset real = read_euroc_dataset(o.out_dir);
  ASSERT_GT(real.imu.size(), 200u);
  // A row of data/euroc/imu/MH_01_imu0_lossy.txt.gz, as it is there.
  const auto row = std::find_if(real.imu.begin(), real.imu.end(),
                                [](const ImuSample& s) { return s.t_ns == 1403636639903555000LL; });
  ASSERT_NE(row, real.imu.end());
  EXPECT_NEAR(row->gyro.x(), 0.0628319, 1e-7);
  EXPECT_NEAR(row->accel.z(), -2.86845, 1e-5);

  sim::SimulationOptions variant = o;
  variant.out_dir = fresh_dir("mh01_variant");
  variant.images_from = o.out_dir;
  sim::ImuErrorModel errors;
  errors.time_offset_s = 0.005;
  variant.imu_errors = errors;
  sim::simulate_sequence(variant);
  const EurocDataset shifted = read_euroc_dataset(variant.out_dir);
  ASSERT_EQ(shifted.cameras[0].frames.size(), real.cameras[0].frames.size());
  EXPECT_TRUE(std::filesystem::equivalent(shifted.cameras[1].frames.back().path, real.cameras[1].frames.back().path));
  const auto moved = std::find_if(shifted.imu.begin(), shifted.imu.end(),
                                  [](const ImuSample& s) { return s.t_ns == 1403636639908555000LL; });
  ASSERT_NE(moved, shifted.imu.end());
  EXPECT_EQ(moved->gyro, row->gyro) << "the sample 5 ms late";

  // Linking needs every image there.
  sim::SimulationOptions longer = variant;
  longer.out_dir = fresh_dir("mh01_longer");
  longer.duration_s = 1.0;
  EXPECT_THROW(sim::simulate_sequence(longer), Error);
  for (const auto& dir : {o.out_dir, variant.out_dir, longer.out_dir}) std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace orbatlas
