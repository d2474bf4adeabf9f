// Place recognition and relocalisation on real EuRoC images (../shared; skipped
// without it): the two loop-closure pairs of a Vicon-room sequence (V2) are
// recognised among the 95 real V1_01 frames, and each stereo pair of a place
// relocalises against a one-keyframe map of the other, consistently both ways.
// The shipped vocabulary was trained with these real frames among its images
// (data/vocabulary/README.md), so this checks the pipeline on real pixels, not
// the vocabulary's generalisation (bench place measures that on renders).
#include <gtest/gtest.h>

#include <filesystem>
#include <opencv2/imgcodecs.hpp>

#include "core/common/data_paths.h"
#include "core/io/euroc_reader.h"
#include "core/io/settings.h"
#include "core/features/orb_extractor.h"
#include "core/relocalization/relocalizer.h"
#include "core/slam/slam_system.h"
#include "core/tracking/stereo_frontend.h"
#include "core/vocabulary/default_vocabulary.h"
#include "core/vocabulary/keyframe_database.h"
#include "tests/support/requirement.h"

namespace orbatlas {
namespace {

std::optional<std::filesystem::path> loop_pairs_dir() {
  const auto shared = shared_euroc_dir();
  if (!shared) return std::nullopt;
  const auto dir = *shared / "extra_images" / "loop_closure_V2_room";
  if (!std::filesystem::exists(dir / "left_img_3.png") || !std::filesystem::is_directory(*shared / "V1_01_micro"))
    return std::nullopt;
  return dir;
}

#define ORBATLAS_REQUIRE_LOOP_PAIRS(var)                             \
  const std::optional<std::filesystem::path> var = loop_pairs_dir(); \
  if (!var) ORBATLAS_NEEDS("the real EuRoC images (../shared/data/euroc or ORBATLAS_SHARED_EUROC)");

cv::Mat gray(const std::filesystem::path& p) {
  cv::Mat m = cv::imread(p.string(), cv::IMREAD_GRAYSCALE);
  EXPECT_FALSE(m.empty()) << p;
  return m;
}

TEST(RealImages, LoopClosurePairsAreRecognisedAmongTheV101Frames) {
  ORBATLAS_REQUIRE_LOOP_PAIRS(dir);
  const Vocabulary vocabulary = Vocabulary::load(default_vocabulary_path());
  OrbExtractorOptions eo;
  eo.n_features = 1000;
  OrbExtractor extractor(eo);
  const auto bow_of = [&](const cv::Mat& image) {
    BowVector bow;
    vocabulary.transform(extractor.extract(image).descriptors, &bow, nullptr);
    return bow;
  };
  // Database: one image of each place (ids 0 and 2) among the 95 real V1_01
  // frames (ids 100..), the same Vicon room with another arrangement.
  KeyframeDatabase database;
  database.add(0, bow_of(gray(*dir / "left_img_0.png")));
  database.add(2, bow_of(gray(*dir / "left_img_2.png")));
  const EurocDataset v1 = read_euroc_dataset(*shared_euroc_dir() / "V1_01_micro");
  KeyframeId id = 100;
  for (const auto& f : v1.cameras[0].frames) database.add(id++, bow_of(gray(f.path)));
  int found = 0;
  for (const auto& [query, place] : {std::pair{1, 0u}, std::pair{3, 2u}}) {
    const auto results = database.query(bow_of(gray(*dir / ("left_img_" + std::to_string(query) + ".png"))), 3);
    ASSERT_FALSE(results.empty());
    const bool hit =
        std::any_of(results.begin(), results.end(), [&](const DatabaseMatch& m) { return m.keyframe == place; });
    found += hit ? 1 : 0;
  }
  EXPECT_EQ(found, 2);
}

// A map of one stereo pair (the first frame initialises it), `other` relocalised against it.
RelocalizationResult relocalise_against(const std::filesystem::path& dir, int map_pair, int query_pair,
                                        const Vocabulary& vocabulary) {
  const SlamSettings settings = read_settings(shipped_config_dir() / "euroc" / "stereo.yaml", SensorType::kStereo);
  Atlas atlas;
  SlamSystemOptions o;
  o.synchronous_mapping = true;
  o.tracker.min_init_stereo_points = 300;  // real frames have ~550 stereo matches; the mats give few
  SlamSystem slam(atlas, settings, vocabulary, o);
  const auto left = [&](int i) { return gray(dir / ("left_img_" + std::to_string(i) + ".png")); };
  const auto right = [&](int i) { return gray(dir / ("right_img_" + std::to_string(i) + ".png")); };
  const TrackResult first = slam.process(1'000'000'000, left(map_pair), right(map_pair));
  EXPECT_TRUE(first.tracked && first.keyframe) << "pair " << map_pair << " did not start a map";
  slam.finish();
  StereoFrontend frontend(settings);
  const FrameCamera cam = frontend.frame_camera();
  Frame frame = frontend.make_frame(2'000'000'000, left(query_pair), right(query_pair));
  return relocalize(frame, vocabulary, atlas.keyframe_index(), cam, frontend.calibration().T_b_c);
}

TEST(RealImages, EachPairOfAPlaceRelocalisesAgainstTheOtherConsistently) {
  ORBATLAS_REQUIRE_LOOP_PAIRS(dir);
  const Vocabulary vocabulary = Vocabulary::load(default_vocabulary_path());
  for (const auto& [a, b] : {std::pair{0, 1}, std::pair{2, 3}}) {
    const RelocalizationResult ab = relocalise_against(*dir, a, b, vocabulary);
    const RelocalizationResult ba = relocalise_against(*dir, b, a, vocabulary);
    ASSERT_TRUE(ab.success) << "pair " << b << " against a map of pair " << a;
    ASSERT_TRUE(ba.success) << "pair " << a << " against a map of pair " << b;
    // Each map's origin is its pair's body: the two relative poses are inverses.
    const Pose3 loop = ab.T_w_b * ba.T_w_b;
    EXPECT_GE(ab.inliers, 50);
    EXPECT_GE(ba.inliers, 50);
    EXPECT_LT(loop.t.norm(), 0.03);                                   // measured 0.0144 and 0.0036 m
    EXPECT_LT(rotation_distance(loop, Pose3()) * 180.0 / M_PI, 0.3);  // measured 0.147 and 0.049 deg
  }
}

}  // namespace
}  // namespace orbatlas
