// orbatlas bench features: ORB extraction, stereo matching, BoW transform and
// keyframe-database query times on a stereo dataset, single thread.
#include <chrono>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <opencv2/core/utility.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>

#include "client/benchmarks.h"
#include "core/common/data_paths.h"
#include "core/common/error.h"
#include "core/common/progress.h"
#include "core/features/orb_extractor.h"
#include "core/features/stereo_rectified.h"
#include "core/io/euroc_reader.h"
#include "core/io/settings.h"
#include "core/tracking/stereo_frontend.h"
#include "core/vocabulary/default_vocabulary.h"
#include "core/vocabulary/keyframe_database.h"
#include "core/vocabulary/vocabulary.h"

namespace orbatlas::cli {
namespace {

using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

}  // namespace

void run_feature_bench(const FeatureBenchOptions& o) {
  o.check();
  cv::setNumThreads(1);  // single-thread figures: OpenCV's resize/blur would otherwise use every core
  const auto config = o.config.empty() ? shipped_config_dir() / "euroc" / "stereo.yaml" : o.config;
  const SlamSettings settings = read_settings(config, SensorType::kStereo);
  ORBATLAS_CHECK(settings.camera1.has_value(), "bench features needs a stereo configuration: " << config.string());
  const auto vocab_path = o.vocabulary.empty() ? default_vocabulary_path() : o.vocabulary;
  const auto t_load = Clock::now();
  const Vocabulary vocabulary = Vocabulary::load(vocab_path);
  const double vocab_load_ms = ms_since(t_load);

  EurocReadOptions ro;
  ro.require_cam1 = true;
  const EurocDataset dataset = read_euroc_dataset(o.dataset, ro);
  const std::vector<DatasetFrame> frames = pair_stereo_frames(dataset);
  ORBATLAS_CHECK(!frames.empty(), "no stereo frames in " << o.dataset.string());

  OrbExtractor left_extractor(orb_options_from(settings)), right_extractor(orb_options_from(settings));
  const StereoRectifier rectifier(settings.camera0, *settings.camera1);

  // Timed frames, spread over the dataset; the database gets up to N keyframes.
  const std::size_t n_time = std::min<std::size_t>(frames.size(), static_cast<std::size_t>(std::max(1, o.frames)));
  const std::size_t n_db =
      std::min<std::size_t>(frames.size(), static_cast<std::size_t>(std::max(1, o.database_keyframes)));
  std::vector<double> extract_ms, stereo_ms, rectify_ms, bow_ms, query_ms;
  std::vector<BowVector> bows;
  std::size_t features_total = 0, stereo_total = 0, corners_total = 0;
  double mean_total = 0.0, contrast_total = 0.0;
  std::vector<cv::KeyPoint> corners;
  Progress progress("bench features", static_cast<std::int64_t>(n_db + n_time));
  KeyframeDatabase database;
  cv::Mat left_rect, right_rect;
  for (std::size_t k = 0; k < n_db; ++k) {
    const DatasetFrame& f = frames[k * frames.size() / n_db];
    const bool timed = (k * n_time) / n_db != ((k + 1) * n_time) / n_db;  // ~n_time of the n_db frames
    const cv::Mat left = read_gray(f.left), right = read_gray(f.right);
    auto t0 = Clock::now();
    rectifier.rectify(left, right, left_rect, right_rect);
    const double t_rect = ms_since(t0);
    t0 = Clock::now();
    const ImageFeatures fl = left_extractor.extract(left_rect);
    const double t_extract = ms_since(t0);
    BowVector bow;
    FeatureVector fv;
    t0 = Clock::now();
    vocabulary.transform(fl.descriptors, &bow, &fv);
    const double t_bow = ms_since(t0);
    if (timed) {
      const ImageFeatures fr = right_extractor.extract(right_rect);
      t0 = Clock::now();
      const StereoDepths depths =
          match_stereo_rectified(fl, left_extractor.pyramid(), fr, right_extractor.pyramid(),
                                 left_extractor.scale_factors(), rectifier.bf(), rectifier.baseline());
      stereo_ms.push_back(ms_since(t0));
      rectify_ms.push_back(t_rect);
      extract_ms.push_back(t_extract);
      bow_ms.push_back(t_bow);
      features_total += fl.keypoints.size();
      stereo_total += depths.matched();
      // Texture as a detector sees it: FAST corners at ORB's initial threshold
      // on the full-resolution image (before ORB's spatial distribution caps them).
      cv::FAST(left_rect, corners, settings.orb.ini_th_fast, true);
      corners_total += corners.size();
      cv::Scalar mean, stddev;
      cv::meanStdDev(left_rect, mean, stddev);
      mean_total += mean[0];
      contrast_total += stddev[0];
    }
    database.add(k, bow);
    bows.push_back(std::move(bow));
    progress.advance();
  }
  // Queries against the full database, excluding the query itself.
  for (std::size_t q = 0; q < n_time; ++q) {
    const std::size_t k = q * bows.size() / n_time;
    const auto t0 = Clock::now();
    const auto results = database.query(bows[k], 3, {k});
    query_ms.push_back(ms_since(t0));
    progress.advance();
  }
  progress.finish();

  const double n = static_cast<double>(extract_ms.size());
  nlohmann::json j = {{"benchmark", "features"},
                      {"dataset", o.dataset.string()},
                      {"frames_timed", extract_ms.size()},
                      {"features_per_frame", static_cast<double>(features_total) / n},
                      {"stereo_matches_per_frame", static_cast<double>(stereo_total) / n},
                      {"fast_corners_per_frame", static_cast<double>(corners_total) / n},
                      {"image_mean", mean_total / n},
                      {"image_contrast", contrast_total / n},
                      {"extract_ms_p50", percentile(extract_ms, 0.5)},
                      {"extract_ms_p95", percentile(extract_ms, 0.95)},
                      {"rectify_ms_p50", percentile(rectify_ms, 0.5)},
                      {"stereo_ms_p50", percentile(stereo_ms, 0.5)},
                      {"bow_ms_p50", percentile(bow_ms, 0.5)},
                      {"query_ms_p50", percentile(query_ms, 0.5)},
                      {"database_keyframes", database.size()},
                      {"vocabulary_words", vocabulary.word_count()},
                      {"vocabulary_load_ms", vocab_load_ms}};
  if (o.json) {
    std::printf("%s\n", j.dump(2).c_str());
    return;
  }
  std::printf("feature benchmark on %s (%zu stereo frames timed, one thread)\n", o.dataset.c_str(), extract_ms.size());
  std::printf(
      "  texture          %.0f FAST corners per frame (threshold %d, level 0), grey mean %.0f, contrast (std) %.0f\n",
      static_cast<double>(corners_total) / n, settings.orb.ini_th_fast, mean_total / n, contrast_total / n);
  std::printf("  ORB extraction   p50 %.2f ms  p95 %.2f ms  (%.0f features per frame)\n", percentile(extract_ms, 0.5),
              percentile(extract_ms, 0.95), static_cast<double>(features_total) / n);
  std::printf("  rectification    p50 %.2f ms per pair\n", percentile(rectify_ms, 0.5));
  std::printf("  stereo matching  p50 %.2f ms per pair  (%.0f matches per frame)\n", percentile(stereo_ms, 0.5),
              static_cast<double>(stereo_total) / n);
  std::printf("  BoW transform    p50 %.3f ms per frame\n", percentile(bow_ms, 0.5));
  std::printf("  database query   p50 %.3f ms with %zu keyframes\n", percentile(query_ms, 0.5), database.size());
  std::printf("  vocabulary       %zu words, loaded in %.1f ms\n", vocabulary.word_count(), vocab_load_ms);
}

}  // namespace orbatlas::cli
