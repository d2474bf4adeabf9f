#pragma once
// Synthetic descriptors with a known cluster structure for the vocabulary
// tests, and the suite VocabularyTest: one vocabulary trained on them for the
// tests that only read it, and a temporary folder for its files.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <random>
#include <set>
#include <string>
#include <system_error>
#include <vector>

#include "core/vocabulary/vocabulary.h"

namespace orbatlas::test {

inline Descriptor random_descriptor(std::mt19937_64& rng) { return {rng(), rng(), rng(), rng()}; }

// Flips `n` distinct random bits.
inline Descriptor flip_bits(Descriptor d, int n, std::mt19937_64& rng) {
  std::set<int> bits;
  while (static_cast<int>(bits.size()) < n) bits.insert(static_cast<int>(rng() % 256));
  for (const int b : bits) d[b / 64] ^= std::uint64_t{1} << (b % 64);
  return d;
}

// 125 cluster centres built as a tree that matches k = 5, L = 3: 5 random group
// prototypes, 5 subgroups per group (32 bits flipped), 5 centres per subgroup (12
// bits flipped). Members are a centre with up to 3 bits flipped.
struct ClusteredData {
  std::vector<Descriptor> centres;
  std::vector<std::vector<Descriptor>> images;           // training descriptors per image
  std::vector<std::vector<std::size_t>> image_clusters;  // cluster of each of them
  std::vector<std::vector<Descriptor>> members;          // per cluster, the training members
};

inline Descriptor member_of(const Descriptor& centre, std::mt19937_64& rng) {
  return flip_bits(centre, static_cast<int>(rng() % 4), rng);
}

// Cluster 0 occurs in every image; the others in about 12 of the 50 images each.
inline ClusteredData make_clustered_data(std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  ClusteredData data;
  for (int g = 0; g < 5; ++g) {
    const Descriptor group = random_descriptor(rng);
    for (int s = 0; s < 5; ++s) {
      const Descriptor sub = flip_bits(group, 32, rng);
      for (int c = 0; c < 5; ++c) data.centres.push_back(flip_bits(sub, 12, rng));
    }
  }
  const std::size_t n_clusters = data.centres.size(), n_images = 50;
  data.members.resize(n_clusters);
  for (std::size_t i = 0; i < n_images; ++i) {
    std::vector<std::size_t> clusters{0};
    for (std::size_t j = 0; j < 30; ++j) clusters.push_back(1 + (i * 30 + j) % (n_clusters - 1));
    std::vector<Descriptor> image;
    std::vector<std::size_t> labels;
    for (const std::size_t c : clusters)
      for (int m = 0; m < 2; ++m) {
        image.push_back(member_of(data.centres[c], rng));
        labels.push_back(c);
        data.members[c].push_back(image.back());
      }
    data.images.push_back(std::move(image));
    data.image_clusters.push_back(std::move(labels));
  }
  return data;
}

inline VocabularyTrainingOptions small_options(std::uint64_t seed = 7) {
  VocabularyTrainingOptions o;
  o.k = 5;
  o.levels = 3;
  o.seed = seed;
  return o;
}

// One vocabulary for the tests that only read it.
class VocabularyTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    data_ = std::make_unique<ClusteredData>(make_clustered_data(42));
    vocabulary_ = std::make_unique<Vocabulary>(Vocabulary::train(data_->images, small_options()));
  }
  static void TearDownTestSuite() {
    vocabulary_.reset();
    data_.reset();
    std::error_code ec;
    std::filesystem::remove_all(temp_dir(), ec);
  }
  static const Vocabulary& voc() { return *vocabulary_; }
  static const ClusteredData& data() { return *data_; }

  static std::filesystem::path temp_dir() {
    return std::filesystem::path(::testing::TempDir()) / ("orbatlas_vocabulary_" + std::to_string(::getpid()));
  }
  static std::filesystem::path temp_path(const std::string& name) {
    std::filesystem::create_directories(temp_dir());
    return temp_dir() / name;
  }

 private:
  static inline std::unique_ptr<ClusteredData> data_;
  static inline std::unique_ptr<Vocabulary> vocabulary_;
};

}  // namespace orbatlas::test
