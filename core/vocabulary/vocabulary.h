#pragma once
// Hierarchical bag-of-words vocabulary over 256-bit binary descriptors: a tree
// of branching factor k and depth L built by k-medians (k-means++ seeding), TF-IDF
// word weights and the L1 score (as DBoW2). Stored as a Cereal binary file with a
// header (k, L, weighting, scoring, descriptor type) and a content hash that maps
// record, so a database built with another vocabulary is recognised.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "core/features/descriptor.h"
#include "core/vocabulary/bow_vector.h"

namespace orbatlas {

struct VocabularyTrainingOptions {
  int k = 10;
  int levels = 5;
  int kmedians_iterations = 10;
  std::uint64_t seed = 1;
  int threads = 0;  // worker threads; 0: std::thread::hardware_concurrency(). The result does not depend on it.
  // Called with (done, total) while training; may be empty.
  std::function<void(std::size_t, std::size_t)> progress;
  void check() const;  // throws Error on invalid values
};

struct VocabularyInfo {
  int k = 0, levels = 0;
  std::size_t words = 0, nodes = 0;
  std::string weighting = "tf-idf", scoring = "l1", descriptor = "orb-256";
  std::string hash;  // hex content hash
  std::size_t training_images = 0, training_descriptors = 0;
};

class Vocabulary {
 public:
  // descriptors_per_image: one vector per training image (for the IDF weights).
  static Vocabulary train(const std::vector<std::vector<Descriptor>>& descriptors_per_image,
                          const VocabularyTrainingOptions& options);
  // Throws DataError on a missing, truncated, corrupt or foreign file.
  static Vocabulary load(const std::filesystem::path& path);
  void save(const std::filesystem::path& path) const;

  // BoW vector of an image, and its direct index at `levels_up` levels above the
  // leaves (DBoW2's convention; ORB-SLAM uses 4 with L = 6, we default to 2 for L = 5).
  void transform(const std::vector<Descriptor>& descriptors, BowVector* bow, FeatureVector* features,
                 int levels_up = 2) const;
  WordId word_of(const Descriptor& d) const;
  double word_weight(WordId w) const;

  // L1 score in [0, 1]: 1 - 0.5 * |a - b|_1 for L1-normalised vectors.
  static double score(const BowVector& a, const BowVector& b);

  const VocabularyInfo& info() const;
  const std::string& hash() const { return info().hash; }
  std::size_t word_count() const { return info().words; }

  // Read-only view of the tree, for tools and tests: node 0 is the root, the
  // children of a node are the ids [first, first + count), the leaves are the words
  // (numbered in node order). Throw Error on an out-of-range id.
  const Descriptor& node_descriptor(NodeId node) const;               // cluster centre (zero for the root)
  NodeId node_parent(NodeId node) const;                              // the root's is the root
  std::pair<NodeId, std::uint32_t> node_children(NodeId node) const;  // (first, count); count 0 for a leaf
  NodeId word_node(WordId word) const;

  Vocabulary(Vocabulary&&) noexcept;
  Vocabulary& operator=(Vocabulary&&) noexcept;
  ~Vocabulary();

 private:
  Vocabulary();
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace orbatlas
