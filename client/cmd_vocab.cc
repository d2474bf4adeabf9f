// orbatlas vocab: train a bag-of-words vocabulary from image folders, and describe
// a vocabulary file.
#include <algorithm>
#include <atomic>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <exception>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <thread>

#include "client/commands.h"
#include "core/common/error.h"
#include "core/common/log.h"
#include "core/common/progress.h"
#include "core/features/orb_extractor.h"
#include "core/vocabulary/vocabulary.h"

namespace orbatlas::cli {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

struct VocabTrainOptions {
  std::vector<fs::path> image_dirs;
  int k = 10;
  int levels = 5;
  int iterations = 10;
  int max_images_per_dir = 0;  // 0: all
  int features = 1000;
  std::uint64_t seed = 1;
  int threads = 0;  // 0: all cores
  fs::path out;
  bool show_progress = true;
};

struct VocabInfoOptions {
  fs::path file;
  bool json = false;
};

bool is_image_file(const fs::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext == ".png" || ext == ".jpg" || ext == ".jpeg";
}

std::vector<fs::path> images_directly_in(const fs::path& dir) {
  std::vector<fs::path> images;
  for (const auto& entry : fs::directory_iterator(dir))
    if (entry.is_regular_file() && is_image_file(entry.path())) images.push_back(entry.path());
  std::sort(images.begin(), images.end());
  return images;
}

// The images of one --images folder: an EuRoC dataset (mav0/cam0/data and
// mav0/cam1/data), or images directly in the folder. At most `max_images`
// (0: all), spread evenly over the sorted list.
std::vector<fs::path> images_of(const fs::path& dir, int max_images) {
  ORBATLAS_CHECK(fs::is_directory(dir), "--images: " << dir.string() << " is not a folder");
  std::vector<fs::path> images;
  const fs::path mav0 = fs::is_directory(dir / "mav0") ? dir / "mav0" : dir;
  if (fs::is_directory(mav0 / "cam0" / "data")) {
    for (const char* cam : {"cam0", "cam1"})
      if (fs::is_directory(mav0 / cam / "data")) {
        const auto found = images_directly_in(mav0 / cam / "data");
        images.insert(images.end(), found.begin(), found.end());
      }
  } else {
    images = images_directly_in(dir);
  }
  ORBATLAS_CHECK(!images.empty(),
                 "--images: no png/jpg/jpeg images in " << dir.string() << " (nor in mav0/cam0/data, mav0/cam1/data)");
  if (max_images > 0 && images.size() > static_cast<std::size_t>(max_images)) {
    std::vector<fs::path> picked;
    const auto n = static_cast<std::size_t>(max_images);
    for (std::size_t i = 0; i < n; ++i) picked.push_back(images[i * images.size() / n]);
    images = std::move(picked);
  }
  return images;
}

struct Extraction {
  std::vector<std::vector<Descriptor>> descriptors;  // per readable image
  std::vector<fs::path> unreadable;
  std::size_t total_descriptors = 0;
};

// ORB descriptors of every image, one extractor per thread.
Extraction extract_all(const std::vector<fs::path>& images, const OrbExtractorOptions& eo, int threads,
                       bool show_progress) {
  std::vector<std::vector<Descriptor>> per_image(images.size());
  std::vector<char> readable(images.size(), 0);
  std::atomic<std::size_t> next{0};
  Progress progress("extracting ORB", static_cast<std::int64_t>(images.size()), show_progress);
  std::exception_ptr error;
  std::mutex error_mutex;
  const auto work = [&]() {
    try {
      OrbExtractor extractor(eo);
      for (std::size_t i = next++; i < images.size(); i = next++) {
        cv::Mat image;
        try {
          image = cv::imread(images[i].string(), cv::IMREAD_GRAYSCALE);
        } catch (const cv::Exception&) {
          image.release();  // a broken file: skipped like an unreadable one
        }
        if (!image.empty()) {
          per_image[i] = extractor.extract(image).descriptors;
          readable[i] = 1;
        }
        progress.advance();
      }
    } catch (...) {
      const std::lock_guard lock(error_mutex);
      if (!error) error = std::current_exception();
      next = images.size();
    }
  };
  {
    std::vector<std::jthread> pool;
    for (int t = 1; t < threads; ++t) pool.emplace_back(work);
    work();
  }
  progress.finish();
  if (error) std::rethrow_exception(error);
  Extraction result;
  for (std::size_t i = 0; i < images.size(); ++i) {
    if (!readable[i]) {
      result.unreadable.push_back(images[i]);
      continue;
    }
    result.total_descriptors += per_image[i].size();
    result.descriptors.push_back(std::move(per_image[i]));
  }
  return result;
}

void run_vocab_train(const VocabTrainOptions& o) {
  const auto t_start = Clock::now();
  OrbExtractorOptions eo;
  eo.n_features = o.features;
  eo.check();
  VocabularyTrainingOptions to;
  to.k = o.k;
  to.levels = o.levels;
  to.kmedians_iterations = o.iterations;
  to.seed = o.seed;
  to.threads = o.threads;
  to.check();  // before the long extraction
  const int threads = o.threads > 0 ? o.threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));

  std::vector<fs::path> images;
  for (const fs::path& dir : o.image_dirs) {
    const auto found = images_of(dir, o.max_images_per_dir);
    std::printf("%s: %zu images\n", dir.string().c_str(), found.size());
    images.insert(images.end(), found.begin(), found.end());
  }
  std::fflush(stdout);

  const Extraction ex = extract_all(images, eo, threads, o.show_progress);
  const double extract_s = seconds_since(t_start);
  constexpr std::size_t kListed = 20;
  for (std::size_t i = 0; i < ex.unreadable.size() && i < kListed; ++i)
    log_warn("skipped unreadable image " + ex.unreadable[i].string());
  if (ex.unreadable.size() > kListed)
    log_warn("... and " + std::to_string(ex.unreadable.size() - kListed) + " more unreadable images");
  ORBATLAS_CHECK(ex.total_descriptors > 0, "no ORB features in the " << ex.descriptors.size() << " readable images");

  std::unique_ptr<Progress> bar;
  std::size_t reported = 0;
  to.progress = [&](std::size_t done, std::size_t total) {
    if (!bar)
      bar = std::make_unique<Progress>("training vocabulary", static_cast<std::int64_t>(total), o.show_progress);
    bar->advance(static_cast<std::int64_t>(done - reported));
    reported = done;
  };
  const auto t_train = Clock::now();
  const Vocabulary vocabulary = Vocabulary::train(ex.descriptors, to);
  if (bar) bar->finish();
  const double train_s = seconds_since(t_train);

  if (o.out.has_parent_path()) fs::create_directories(o.out.parent_path());
  vocabulary.save(o.out);
  const VocabularyInfo& info = vocabulary.info();
  std::printf("trained on %zu images (%zu ORB descriptors, %zu unreadable images skipped)\n", ex.descriptors.size(),
              ex.total_descriptors, ex.unreadable.size());
  std::printf("vocabulary: k %d, %d levels: %zu words, %zu nodes, hash %s\n", info.k, info.levels, info.words,
              info.nodes, info.hash.c_str());
  std::printf("extraction %.1f s, training %.1f s (%.2f M descriptors/s over %d levels)\n", extract_s, train_s,
              static_cast<double>(ex.total_descriptors) * 1e-6 / std::max(train_s, 1e-9), info.levels);
  std::printf("wrote %s (%.1f MB)\n", o.out.string().c_str(), static_cast<double>(fs::file_size(o.out)) * 1e-6);
}

void run_vocab_info(const VocabInfoOptions& o) {
  const auto t0 = Clock::now();
  const Vocabulary vocabulary = Vocabulary::load(o.file);
  const double load_ms = seconds_since(t0) * 1e3;
  const VocabularyInfo& info = vocabulary.info();
  const std::uintmax_t bytes = fs::file_size(o.file);
  if (o.json) {
    const nlohmann::json j = {{"file", o.file.string()},
                              {"k", info.k},
                              {"levels", info.levels},
                              {"words", info.words},
                              {"nodes", info.nodes},
                              {"weighting", info.weighting},
                              {"scoring", info.scoring},
                              {"descriptor", info.descriptor},
                              {"hash", info.hash},
                              {"training_images", info.training_images},
                              {"training_descriptors", info.training_descriptors},
                              {"file_bytes", bytes},
                              {"load_ms", load_ms}};
    std::printf("%s\n", j.dump(2).c_str());
    return;
  }
  std::printf("%s\n", o.file.string().c_str());
  std::printf("  tree:       k %d, %d levels, %zu words, %zu nodes\n", info.k, info.levels, info.words, info.nodes);
  std::printf("  weighting:  %s, scoring %s, descriptor %s\n", info.weighting.c_str(), info.scoring.c_str(),
              info.descriptor.c_str());
  std::printf("  hash:       %s\n", info.hash.c_str());
  std::printf("  training:   %zu images, %zu descriptors\n", info.training_images, info.training_descriptors);
  std::printf("  file:       %.2f MB, loaded in %.1f ms\n", static_cast<double>(bytes) * 1e-6, load_ms);
}

}  // namespace

void register_vocab_command(CLI::App& app) {
  auto* vocab = app.add_subcommand("vocab", "Bag-of-words vocabulary: train one from images, or describe a file");
  vocab->require_subcommand(1);

  auto train = std::make_shared<VocabTrainOptions>();
  auto* t = vocab->add_subcommand("train", "Train a vocabulary (hierarchical k-medians over ORB descriptors, TF-IDF)");
  t->add_option("--images", train->image_dirs,
                "Image folders: images directly inside, or EuRoC datasets (mav0/cam0/data, mav0/cam1/data)")
      ->required()
      ->check(CLI::ExistingDirectory);
  t->add_option("--out", train->out, "Vocabulary file to write")->required();
  t->add_option("--k", train->k, "Branching factor")->capture_default_str();
  t->add_option("--levels", train->levels, "Depth of the tree (words are at most k^levels)")->capture_default_str();
  t->add_option("--iterations", train->iterations, "k-medians iterations per node (at most)")->capture_default_str();
  t->add_option("--max-images-per-dir", train->max_images_per_dir,
                "Use at most N images of each folder, evenly spread (0: all)")
      ->capture_default_str();
  t->add_option("--features", train->features, "ORB features per image")->capture_default_str();
  t->add_option("--seed", train->seed, "Seed of the k-means++ seeding (same seed and images, same vocabulary)")
      ->capture_default_str();
  t->add_option("--threads", train->threads, "Worker threads (default: all cores)");
  t->add_flag("!--no-progress", train->show_progress, "Do not print progress");
  t->callback([train]() { run_vocab_train(*train); });

  auto info = std::make_shared<VocabInfoOptions>();
  auto* i = vocab->add_subcommand("info", "Describe a vocabulary file (checks its hash) and time its loading");
  i->add_option("file", info->file, "Vocabulary file")->required();
  i->add_flag("--json", info->json, "Print one JSON object");
  i->callback([info]() { run_vocab_info(*info); });
}

}  // namespace orbatlas::cli
