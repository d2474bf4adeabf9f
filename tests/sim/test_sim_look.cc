// The simulator's `real` look: auto exposure, vignetting, signal-dependent
// noise and clipping (RealCamera) against their exact laws; sparse textures
// give far fewer corners than clean ones; a real-look dataset is darker for
// MH_04, blurred by motion, written with the nominal calibration, and its IMU
// vibrates.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>

#include "core/common/error.h"
#include "core/io/euroc_reader.h"
#include "core/sim/real_camera.h"
#include "core/sim/sequence_simulator.h"
#include "core/sim/texture.h"

namespace orbatlas {
namespace {

std::filesystem::path fresh_dir(const std::string& name) {
  const auto dir =
      std::filesystem::temp_directory_path() / ("orbatlas_test_look_" + std::to_string(::getpid()) + "_" + name);
  std::filesystem::remove_all(dir);
  return dir;
}

TEST(RealCamera, AutoExposureTradesExposureThenGainThenDarkness) {
  sim::RealCameraOptions o;
  o.drift = 0.0;
  o.stereo_mismatch = 0.0;
  // Well lit: the base exposure, no gain, the clean brightness.
  sim::RealCamera lit(o, 64, 48, 0, 1);
  const sim::Exposure e1 = lit.exposure_at(0);
  EXPECT_NEAR(e1.exposure_s, o.base_exposure_ms * 1e-3, 1e-12);
  EXPECT_NEAR(e1.gain, 1.0, 1e-12);
  EXPECT_NEAR(e1.brightness, 1.0, 1e-12);
  // Half the light: twice the exposure, still no gain.
  o.illumination = 0.5;
  const sim::Exposure e2 = sim::RealCamera(o, 64, 48, 0, 1).exposure_at(0);
  EXPECT_NEAR(e2.exposure_s, 2.0 * o.base_exposure_ms * 1e-3, 1e-12);
  EXPECT_NEAR(e2.gain, 1.0, 1e-12);
  EXPECT_NEAR(e2.brightness, 1.0, 1e-12);
  // Dark (MH_04/MH_05): exposure and gain at their limits, the image darker.
  o.illumination = 0.12;
  const sim::Exposure e3 = sim::RealCamera(o, 64, 48, 0, 1).exposure_at(0);
  EXPECT_NEAR(e3.exposure_s, o.max_exposure_ms * 1e-3, 1e-12);
  EXPECT_NEAR(e3.gain, o.max_gain, 1e-12);
  EXPECT_NEAR(e3.brightness, 0.12 * o.max_exposure_ms / o.base_exposure_ms * o.max_gain, 1e-12);
  EXPECT_LT(e3.brightness, 0.7);
}

TEST(RealCamera, TheTwoCamerasDriftApartOverTime) {
  sim::RealCameraOptions o;  // default drift and mismatch
  sim::RealCamera left(o, 64, 48, 0, 5), right(o, 64, 48, 1, 5);
  double min_ratio = 10.0, max_ratio = 0.0, min_b = 10.0, max_b = 0.0;
  for (int k = 0; k < 400; ++k) {
    const TimestampNs t = static_cast<TimestampNs>(k) * 50'000'000;  // 20 s
    const double l = left.exposure_at(t).brightness, r = right.exposure_at(t).brightness;
    min_ratio = std::min(min_ratio, l / r);
    max_ratio = std::max(max_ratio, l / r);
    min_b = std::min(min_b, l);
    max_b = std::max(max_b, l);
  }
  EXPECT_GT(max_b - min_b, 0.2);  // brightness changes over time...
  EXPECT_LT(max_b, 1.0 + o.drift + o.stereo_mismatch);
  EXPECT_GT(max_ratio - min_ratio, 0.1);  // ...and differently in the two cameras
}

TEST(RealCamera, VignettingNoiseAndClippingFollowTheirLaws) {
  sim::RealCameraOptions o;
  o.drift = 0.0;
  o.stereo_mismatch = 0.0;
  o.optics_blur_px = 0.0;
  const int w = 200, h = 100;
  sim::RealCamera camera(o, w, h, 0, 3);
  const sim::Exposure e = camera.exposure_at(0);
  // Noise-free law at the centre and a corner: 1 - vignetting * r^2.5.
  sim::RealCameraOptions noiseless = o;
  noiseless.read_noise = 0.0;
  noiseless.shot_noise = 0.0;
  sim::RealCamera quiet(noiseless, w, h, 0, 3);
  cv::Mat flat(h, w, CV_32FC1, cv::Scalar(200.0)), out;
  quiet.develop(flat, e, out, 1);
  EXPECT_NEAR(out.at<std::uint8_t>(h / 2, w / 2), 200, 1);
  EXPECT_NEAR(out.at<std::uint8_t>(0, 0), std::lround(200.0 * (1.0 - o.vignetting)), 1);
  // Clipping: far too bright stays 255.
  quiet.develop(cv::Mat(h, w, CV_32FC1, cv::Scalar(900.0)), e, out, 1);
  EXPECT_EQ(out.at<std::uint8_t>(h / 2, w / 2), 255);
  // Noise grows with the signal: variance read^2 + shot * signal (gain 1).
  const auto noise_std = [&](double level) {
    cv::Mat img;
    camera.develop(cv::Mat(h, w, CV_32FC1, cv::Scalar(level)), e, img, 7);
    cv::Mat centre;
    img(cv::Rect(w / 2 - 20, h / 2 - 10, 40, 20)).convertTo(centre, CV_64F);
    cv::Scalar mean, stddev;
    cv::meanStdDev(centre, mean, stddev);
    return stddev[0];
  };
  const double dark = noise_std(20.0), bright = noise_std(180.0);
  EXPECT_NEAR(dark, std::sqrt(o.read_noise * o.read_noise + o.shot_noise * 20.0), 0.35);
  EXPECT_NEAR(bright, std::sqrt(o.read_noise * o.read_noise + o.shot_noise * 180.0), 0.45);
  EXPECT_GT(bright, dark * 1.5);
}

TEST(RealCamera, MotionDecidesHowManyRendersAreAveraged) {
  sim::RealCameraOptions o;
  sim::RealCamera camera(o, 64, 48, 0, 1);
  EXPECT_EQ(camera.subframes(0.0, 0.01), 1);
  EXPECT_EQ(camera.subframes(300.0, 0.01), 3);  // 3 px of motion during the exposure
  EXPECT_EQ(camera.subframes(1e5, 0.01), o.max_blur_subframes);
}

int fast_corners(const cv::Mat& image) {
  std::vector<cv::KeyPoint> corners;
  cv::FAST(image, corners, 20, true);
  return static_cast<int>(corners.size());
}

TEST(SparseTexture, HasFarFewerCornersThanTheCleanOne) {
  sim::TextureRequest req;
  req.width_m = 3.0;
  req.height_m = 2.0;
  req.seed = 9;
  const int clean = fast_corners(sim::make_texture(req).levels[2]);  // ~2 cm texels, as seen from a few metres
  req.sparse = true;
  const int sparse = fast_corners(sim::make_texture(req).levels[2]);
  RecordProperty("clean_corners", clean);
  RecordProperty("sparse_corners", sparse);
  EXPECT_GT(sparse, 0);          // sparse details are there...
  EXPECT_LT(sparse * 3, clean);  // ...but far fewer corners
}

TEST(SequenceSimulator, RealLookIsDarkerForMh04BlurredAndKeepsTheNominalCalibration) {
  const auto render = [](const std::string& sequence, sim::Look look, double start, const std::string& name) {
    sim::SimulationOptions o;
    o.sequence = sequence;
    o.out_dir = fresh_dir(name);
    o.start_s = start;
    o.duration_s = 0.2;
    o.look = look;
    o.show_progress = false;
    return std::make_pair(o.out_dir, sim::simulate_sequence(o));
  };
  const auto mean_grey = [](const std::filesystem::path& dir) {
    const EurocDataset ds = read_euroc_dataset(dir);
    double sum = 0.0;
    for (const auto& f : ds.cameras[0].frames) sum += cv::mean(cv::imread(f.path.string(), cv::IMREAD_GRAYSCALE))[0];
    return sum / static_cast<double>(ds.cameras[0].frames.size());
  };
  const auto [clean_dir, clean] = render("MH_04", sim::Look::kClean, 30.0, "clean04");
  const auto [real_dir, real] = render("MH_04", sim::Look::kReal, 30.0, "real04");
  EXPECT_EQ(real.frames, clean.frames);
  EXPECT_NEAR(real.mean_exposure_ms, 10.0, 1e-6);  // the dark hall: exposure at its limit
  EXPECT_GT(real.subframes_per_image, 2.0);        // MH_04 at 30 s moves several pixels in 10 ms (3.8 renders)
  EXPECT_LT(mean_grey(real_dir), 0.8 * mean_grey(clean_dir));
  // sensor.yaml holds the nominal calibration, whatever the renders used.
  const EurocDataset ds = read_euroc_dataset(real_dir);
  EXPECT_NEAR(ds.cameras[0].calibration.fx, 458.654, 1e-9);
  EXPECT_NEAR(ds.cameras[0].calibration.cx, 367.215, 1e-9);
  std::filesystem::remove_all(clean_dir);
  std::filesystem::remove_all(real_dir);
}

TEST(SequenceSimulator, UnknownLookIsAClearError) { EXPECT_THROW(sim::parse_look("shiny"), Error); }

}  // namespace
}  // namespace orbatlas
