// The TUM RGB-D layout: a written dataset reads back identically (images,
// 16-bit depth, exact timestamps, ground truth), colour images pair with the
// nearest depth image within 0.02 s, and bad datasets get a clear error.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "core/common/error.h"
#include "core/io/tum_rgbd.h"

namespace orbatlas {
namespace {

namespace fs = std::filesystem;

struct TempDir {
  fs::path path;
  TempDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    path =
        fs::temp_directory_path() / ("orbatlas_tum_rgbd_" + std::string(info->name()) + "_" + std::to_string(getpid()));
    fs::remove_all(path);
  }
  ~TempDir() { fs::remove_all(path); }
};

// Random images, the same for the same seed.
cv::Mat gray(int seed) {
  cv::Mat m(48, 64, CV_8UC1);
  cv::RNG(static_cast<std::uint64_t>(seed) + 1).fill(m, cv::RNG::UNIFORM, 0, 256);
  return m;
}

cv::Mat depth(int seed) {
  cv::Mat m(48, 64, CV_16UC1);
  cv::RNG(static_cast<std::uint64_t>(seed) + 100).fill(m, cv::RNG::UNIFORM, 0, 65536);
  return m;
}

TEST(TumRgbd, AWrittenDatasetReadsBackIdentically) {
  TempDir dir;
  const TimestampNs t0 = 1305031102'175304123;
  Trajectory gt;
  {
    TumRgbdWriter writer(dir.path);
    for (int i = 0; i < 4; ++i) {
      const TimestampNs t = t0 + i * 33'333'333;
      writer.add(t, gray(i), t + 7'000'001, depth(i));  // depth 7 ms after the colour image
      gt.push_back({t, Pose3(Eigen::Quaterniond(Eigen::AngleAxisd(0.1 * i, Eigen::Vector3d::UnitZ())),
                             Eigen::Vector3d(0.5 * i, -0.25, 1.0))});
    }
    writer.finish(gt);
    EXPECT_THROW(TumRgbdWriter again(dir.path), Error);  // never over an existing dataset
  }
  const TumRgbdDataset d = read_tum_rgbd(dir.path);
  ASSERT_EQ(d.frames.size(), 4u);
  EXPECT_EQ(d.unpaired, 0u);
  for (int i = 0; i < 4; ++i) {
    const RgbdFrame& f = d.frames[static_cast<std::size_t>(i)];
    EXPECT_EQ(f.t_ns, t0 + i * 33'333'333);
    EXPECT_EQ(f.depth_t_ns, f.t_ns + 7'000'001);
    EXPECT_EQ(cv::norm(cv::imread(f.rgb.string(), cv::IMREAD_UNCHANGED), gray(i), cv::NORM_INF), 0.0);
    EXPECT_EQ(cv::norm(read_depth_image(f.depth, 64, 48), depth(i), cv::NORM_INF), 0.0);
  }
  ASSERT_EQ(d.ground_truth.size(), gt.size());
  for (std::size_t i = 0; i < gt.size(); ++i) {
    EXPECT_EQ(d.ground_truth[i].t_ns, gt[i].t_ns);
    EXPECT_LT((d.ground_truth[i].pose.t - gt[i].pose.t).norm(), 1e-9);
  }
  const auto pairs = rgbd_image_pairs(d);
  ASSERT_EQ(pairs.size(), 4u);
  EXPECT_EQ(pairs[2].left, d.frames[2].rgb);
  EXPECT_EQ(pairs[2].right, d.frames[2].depth);
  const auto states = ground_truth_states(d);
  ASSERT_EQ(states.size(), gt.size());
  EXPECT_EQ(states[3].t_ns, gt[3].t_ns);
  EXPECT_LT((states[3].T_w_b.t - gt[3].pose.t).norm(), 1e-9);
  EXPECT_THROW(read_depth_image(d.frames[0].depth, 32, 48), DataError);  // another camera's size
  EXPECT_THROW(read_depth_image(d.frames[0].rgb, 64, 48), DataError);    // 8-bit: not a depth image
}

// TUM's own files: seconds with 6 decimals, comments, colour and depth at
// their own instants; a colour image 30 ms from any depth image is skipped.
TEST(TumRgbd, ColourImagesPairWithTheNearestDepthImage) {
  TempDir dir;
  fs::create_directories(dir.path / "rgb");
  fs::create_directories(dir.path / "depth");
  for (const char* f : {"rgb/a.png", "rgb/b.png", "rgb/c.png"}) cv::imwrite((dir.path / f).string(), gray(1));
  for (const char* f : {"depth/a.png", "depth/b.png"}) cv::imwrite((dir.path / f).string(), depth(1));
  std::ofstream(dir.path / "rgb.txt") << "# color images\n# timestamp filename\n"
                                         "1305031102.175304 rgb/a.png\n1305031102.211214 rgb/b.png\n"
                                         "1305031102.275326 rgb/c.png\n";
  std::ofstream(dir.path / "depth.txt") << "# depth\n1305031102.160407 depth/a.png\n1305031102.226738 depth/b.png\n";
  const TumRgbdDataset d = read_tum_rgbd(dir.path);
  ASSERT_EQ(d.frames.size(), 2u);
  EXPECT_EQ(d.unpaired, 1u);  // c: 49 ms from b
  EXPECT_EQ(d.frames[0].depth, dir.path / "depth/a.png");
  EXPECT_EQ(d.frames[1].depth, dir.path / "depth/b.png");
  EXPECT_EQ(d.frames[0].t_ns, 1305031102'175304000);
  EXPECT_TRUE(d.ground_truth.empty());

  std::ofstream(dir.path / "depth.txt") << "1305031102.160407 depth/missing.png\n";
  try {
    read_tum_rgbd(dir.path);
    FAIL() << "a missing image was accepted";
  } catch (const DataError& e) {
    EXPECT_NE(std::string(e.what()).find("depth.txt:1"), std::string::npos) << e.what();
  }
  std::ofstream(dir.path / "depth.txt") << "yesterday depth/a.png\n";
  EXPECT_THROW(read_tum_rgbd(dir.path), DataError);
  fs::remove(dir.path / "rgb.txt");
  EXPECT_THROW(read_tum_rgbd(dir.path), DataError);
}

}  // namespace
}  // namespace orbatlas
