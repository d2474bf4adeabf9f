// TUM trajectory files: exact round trip, ORB-SLAM3's ns timestamps, errors, gzip,
// and read_any_ground_truth's input forms; EuRoC trajectory csv files.
#include <gtest/gtest.h>
#include <unistd.h>
#include <zlib.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "core/common/data_paths.h"
#include "core/common/error.h"
#include "core/io/euroc_trajectory.h"
#include "core/io/euroc_writer.h"
#include "core/io/tum_trajectory.h"

namespace orbatlas {
namespace {

namespace fs = std::filesystem;

fs::path temp_file(const std::string& name) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  return fs::temp_directory_path() /
         ("orbatlas_tum_" + std::string(info->name()) + "_" + std::to_string(getpid()) + "_" + name);
}

void write_text(const fs::path& path, const std::string& text) { std::ofstream(path, std::ios::trunc) << text; }

void write_gzip(const fs::path& path, const std::string& text) {
  gzFile f = gzopen(path.c_str(), "wb");
  ASSERT_NE(f, nullptr);
  ASSERT_EQ(gzwrite(f, text.data(), static_cast<unsigned>(text.size())), static_cast<int>(text.size()));
  ASSERT_EQ(gzclose(f), Z_OK);
}

Trajectory make_trajectory() {
  Trajectory t;
  for (int i = 0; i < 50; ++i) {
    StampedPose s;
    s.t_ns = 1403636580838560000 + i * 5'000'001 + (i % 7);  // odd nanoseconds
    s.pose = Pose3(Eigen::Quaterniond(Eigen::AngleAxisd(0.05 * i - 1.0, Eigen::Vector3d(1, -2, 0.5).normalized())),
                   Eigen::Vector3d(4.688319 - 0.01 * i, -1.786938 + 1e-9 * i, 0.783338 * i));
    t.push_back(s);
  }
  return t;
}

std::string read_error(const fs::path& path) {
  try {
    read_tum_trajectory(path);
  } catch (const DataError& e) {
    return e.what();
  }
  return "";
}

TEST(Tum, WriteThenReadKeepsEveryNanosecondAndPose) {
  const Trajectory want = make_trajectory();
  const fs::path path = temp_file("roundtrip.txt");
  write_tum_trajectory(path, want);
  const Trajectory got = read_tum_trajectory(path);
  fs::remove(path);
  ASSERT_EQ(got.size(), want.size());
  for (std::size_t i = 0; i < got.size(); ++i) {
    EXPECT_EQ(got[i].t_ns, want[i].t_ns);
    EXPECT_LT((got[i].pose.t - want[i].pose.t).cwiseAbs().maxCoeff(), 1e-9);
    // Quaternion components are written with 9 decimals (error <= 5e-10 each) and
    // renormalised on reading, which can add up to |q_i| * 1e-9.
    EXPECT_LT((got[i].pose.q.coeffs() - want[i].pose.q.coeffs()).cwiseAbs().maxCoeff(), 1.5e-9);
  }
}

TEST(Tum, ReadsSecondsExactly) {
  const fs::path path = temp_file("seconds.txt");
  write_text(path,
             "# timestamp(s) tx ty tz qx qy qz qw\n"
             "1403636580.83856 4.688319 -1.786938 0.783338 -0.153029 -0.827383 -0.082152 0.534108\n"
             "\n"
             "1403636580.843560001\t4.688177  -1.786770 0.787350 0 0 0 1\r\n");
  const Trajectory t = read_tum_trajectory(path);
  fs::remove(path);
  ASSERT_EQ(t.size(), 2u);
  EXPECT_EQ(t[0].t_ns, 1403636580838560000);
  EXPECT_EQ(t[1].t_ns, 1403636580843560001);
  EXPECT_DOUBLE_EQ(t[0].pose.t.x(), 4.688319);
  // qx qy qz qw order
  EXPECT_NEAR(t[0].pose.q.w(), 0.534108, 1e-6);
  EXPECT_NEAR(t[0].pose.q.x(), -0.153029, 1e-6);
  EXPECT_NEAR(t[0].pose.q.z(), -0.082152, 1e-6);
  EXPECT_EQ(t[1].pose.q.w(), 1.0);
}

TEST(Tum, ReadsOrbSlam3NanosecondTimestamps) {
  const fs::path path = temp_file("orbslam3.txt");
  write_text(path,
             "1403636586363555584.000000 -0.002911233 -0.005921433 -0.018368252 -0.004799613 -0.038713723 "
             "0.008630877 0.999201596\n"
             "1403636586413555456.000000 -0.000461348 -0.014742880 -0.177309170 -0.001206033 -0.052378301 "
             "0.013089301 0.998540819\n"
             "1403636586463555584 -0.015277470 -0.012896973 -0.219721287 -0.001700193 -0.062444508 0.012784095 "
             "0.997965157\n");
  const Trajectory t = read_tum_trajectory(path);
  fs::remove(path);
  ASSERT_EQ(t.size(), 3u);
  EXPECT_EQ(t[0].t_ns, 1403636586363555584);
  EXPECT_EQ(t[1].t_ns, 1403636586413555456);
  EXPECT_EQ(t[2].t_ns, 1403636586463555584);
  EXPECT_NEAR(t[1].pose.t.z(), -0.177309170, 1e-12);
}

TEST(Tum, MalformedLinesAreErrorsWithFileAndLine) {
  const fs::path path = temp_file("bad.txt");
  write_text(path, "# header\n1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 1\n");
  std::string msg = read_error(path);
  EXPECT_NE(msg.find(path.string() + ":3:"), std::string::npos) << msg;
  EXPECT_NE(msg.find("expected 8 fields"), std::string::npos) << msg;

  write_text(path, "1.0 0 0 0 0 0 0 1\n2.0 0 0 zero 0 0 0 1\n");
  EXPECT_NE(read_error(path).find(":2: not a number"), std::string::npos);

  write_text(path, "1.0x 0 0 0 0 0 0 1\n");
  EXPECT_NE(read_error(path).find(":1: bad timestamp"), std::string::npos);

  write_text(path, "1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 0 1.1\n");
  EXPECT_NE(read_error(path).find(":2: quaternion is not unit"), std::string::npos);

  write_text(path, "1.0 0 0 0 0 0 0 1\n1.0 0 0 0 0 0 0 1\n");
  EXPECT_NE(read_error(path).find(":2: timestamp"), std::string::npos);

  write_text(path, "2.0 0 0 0 0 0 0 1\n1.5 0 0 0 0 0 0 1\n");
  EXPECT_NE(read_error(path).find(":2: timestamp"), std::string::npos);
  fs::remove(path);

  EXPECT_NE(read_error(temp_file("absent.txt")).find("cannot open"), std::string::npos);
}

TEST(Tum, ReadsGzip) {
  const fs::path plain = temp_file("plain.txt");
  const fs::path gz = temp_file("compressed.txt.gz");
  write_tum_trajectory(plain, make_trajectory());
  std::ifstream in(plain);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  write_gzip(gz, text);
  const Trajectory a = read_tum_trajectory(plain), b = read_tum_trajectory(gz);
  fs::remove(plain);
  fs::remove(gz);
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].t_ns, b[i].t_ns);
    EXPECT_EQ(a[i].pose.t, b[i].pose.t);
  }
}

TEST(Tum, ReadsShippedGroundTruthAndOrbSlam3Output) {
  const Trajectory gt = read_tum_trajectory(shipped_data_dir() / "euroc" / "groundtruth" / "MH_01_easy.txt.gz");
  ASSERT_EQ(gt.size(), 36382u);
  EXPECT_EQ(gt.front().t_ns, 1403636580838560000);
  const Trajectory est =
      read_tum_trajectory(shipped_data_dir() / "euroc" / "peer_trajectories" / "orbslam3_MH01_monoi_frames.txt.gz");
  ASSERT_EQ(est.size(), 3550u);
  EXPECT_EQ(est.front().t_ns, 1403636586363555584);
}

TEST(Tum, ReadAnyGroundTruthTakesTumAslCsvAndDatasetFolders) {
  const fs::path root = temp_file("dataset");
  fs::remove_all(root);
  std::vector<GroundTruthState> states;
  for (int i = 0; i < 5; ++i) {
    GroundTruthState s;
    s.t_ns = 1403715273262142976 + i * 5'000'000;
    s.T_w_b = Pose3(Eigen::Quaterniond(Eigen::AngleAxisd(0.1 * i, Eigen::Vector3d::UnitZ())),
                    Eigen::Vector3d(i, 2.0 * i, -1.0));
    states.push_back(s);
  }
  {
    CameraCalibration cam;
    cam.fx = cam.fy = 400;
    cam.cx = 320;
    cam.cy = 240;
    cam.width = 640;
    cam.height = 480;
    cam.rate_hz = 20;
    cam.distortion = {0, 0, 0, 0};
    EurocWriter writer(root, {cam}, ImuCalibration{});
    writer.write_ground_truth(states);
    writer.close();
  }
  const fs::path csv = root / "mav0" / "state_groundtruth_estimate0" / "data.csv";
  const fs::path tum = temp_file("gt.txt");
  Trajectory want;
  for (const auto& s : states) want.push_back({s.t_ns, s.T_w_b});
  write_tum_trajectory(tum, want);

  for (const fs::path& input : {root, root / "mav0", csv, tum}) {
    SCOPED_TRACE(input.string());
    const Trajectory got = read_any_ground_truth(input);
    ASSERT_EQ(got.size(), want.size());
    for (std::size_t i = 0; i < got.size(); ++i) {
      EXPECT_EQ(got[i].t_ns, want[i].t_ns);
      EXPECT_LT((got[i].pose.t - want[i].pose.t).norm(), 1e-9);
      EXPECT_LT(got[i].pose.q.angularDistance(want[i].pose.q), 1e-9);
    }
  }
  EXPECT_THROW(read_any_ground_truth(root / "mav0" / "cam0"), DataError);
  EXPECT_THROW(read_any_ground_truth(root / "absent.txt"), DataError);
  fs::remove_all(root);
  fs::remove(tum);
}

// The EuRoC csv (`--format euroc`): every nanosecond and pose back, map
// comments skipped, read by read_any_ground_truth (what `orbatlas eval --est`
// and `--gt` use) as the same trajectory as its TUM twin, and bad lines are
// errors with file and line.
TEST(EurocTrajectory, WriteThenReadKeepsEveryNanosecondAndPoseAsTumDoes) {
  const Trajectory want = make_trajectory();
  std::vector<std::uint64_t> maps(want.size(), 0);
  for (std::size_t i = 20; i < maps.size(); ++i) maps[i] = 3;
  const fs::path csv = temp_file("roundtrip.csv"), tum = temp_file("roundtrip.txt");
  write_trajectory(csv, want, maps, TrajectoryFormat::kEuroc);
  write_trajectory(tum, want, maps, TrajectoryFormat::kTum);
  const std::string text = format_euroc_trajectory(want, maps);
  EXPECT_EQ(text.rfind("#timestamp [ns],p_RS_R_x [m]", 0), 0u);
  EXPECT_NE(text.find("\n# map 3\n1403636580938560026,"), std::string::npos) << text.substr(0, 400);
  const Trajectory got = read_euroc_trajectory(csv);
  const Trajectory any = read_any_ground_truth(csv);
  const Trajectory from_tum = read_any_ground_truth(tum);
  fs::remove(csv);
  fs::remove(tum);
  ASSERT_EQ(got.size(), want.size());
  ASSERT_EQ(any.size(), want.size());
  ASSERT_EQ(from_tum.size(), want.size());
  for (std::size_t i = 0; i < got.size(); ++i) {
    EXPECT_EQ(got[i].t_ns, want[i].t_ns);
    EXPECT_EQ(any[i].t_ns, want[i].t_ns);
    EXPECT_LT((got[i].pose.t - want[i].pose.t).cwiseAbs().maxCoeff(), 1e-9);
    EXPECT_LT((got[i].pose.q.coeffs() - want[i].pose.q.coeffs()).cwiseAbs().maxCoeff(), 1.5e-9);
    EXPECT_EQ(any[i].pose.t, from_tum[i].pose.t);  // the same digits in both formats
    EXPECT_EQ(any[i].pose.q.coeffs(), from_tum[i].pose.q.coeffs());
  }
  EXPECT_EQ(parse_trajectory_format("euroc"), TrajectoryFormat::kEuroc);
  EXPECT_THROW(parse_trajectory_format("kitti"), Error);

  const auto error = [](const std::string& lines) {
    try {
      parse_euroc_trajectory(lines, "t.csv");
    } catch (const DataError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(error("1,0,0,0,1,0,0\n").find("t.csv:1: expected 8 fields"), std::string::npos);
  EXPECT_NE(error("# c\n1.5,0,0,0,1,0,0,0\n").find("t.csv:2: the timestamp '1.5' is not an integer"),
            std::string::npos);
  EXPECT_NE(error("5,0,0,0,1,0,0,0\n5,0,0,0,1,0,0,0\n").find("t.csv:2: timestamp 5 is not after 5"), std::string::npos);
  EXPECT_NE(error("5,0,0,0,2,0,0,0\n").find("not unit"), std::string::npos);
  EXPECT_NE(error("5,nan,0,0,1,0,0,0\n").find("non-finite"), std::string::npos);
}

}  // namespace
}  // namespace orbatlas
