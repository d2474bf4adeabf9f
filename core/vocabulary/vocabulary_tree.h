#pragma once
// Internal to the vocabulary library: the flat tree behind Vocabulary. Node 0 is
// the root; the children of a node are the contiguous ids [first_child, first_child
// + child_count); nodes without children are the words. Arrays, not node objects,
// so that descending compares a query with k consecutive 32-byte descriptors and
// loading is a few bulk reads.
#include <cstdint>
#include <limits>
#include <vector>

#include "core/features/descriptor.h"
#include "core/vocabulary/bow_vector.h"

// Hamming distances use the POPCNT instruction when the CPU has it (the x86-64
// baseline the project builds for has not, and std::popcount then becomes a
// library call): hot loops are compiled twice and picked at load time.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__SANITIZE_THREAD__)
#define ORBATLAS_POPCNT_CLONES __attribute__((target_clones("popcnt", "default")))
#else
#define ORBATLAS_POPCNT_CLONES
#endif

namespace orbatlas::vocabulary_detail {

constexpr WordId kNoWord = std::numeric_limits<WordId>::max();

struct VocabularyTree {
  int k = 0, levels = 0;
  // Per node (stored in the file).
  std::vector<Descriptor> descriptors;                  // cluster centre; zero for the root
  std::vector<std::uint32_t> first_child, child_count;  // 0, 0 for a leaf
  // Per word (stored in the file).
  std::vector<NodeId> word_nodes;    // the leaf of each word, in increasing node order
  std::vector<double> word_weights;  // IDF
  // Derived by derive_and_check() (not stored).
  std::vector<WordId> node_words;    // word of a leaf, kNoWord for an inner node
  std::vector<NodeId> parents;       // root: 0
  std::vector<std::uint8_t> depths;  // root: 0

  std::size_t node_count() const { return descriptors.size(); }
  // Checks the structure (sizes, child ranges, one parent per node, depth <= levels,
  // words are exactly the leaves in node order, finite non-negative weights) and fills
  // the derived arrays. Throws Error describing the first inconsistency.
  void derive_and_check();
};

// Descends from the root to a leaf for each descriptor, choosing the nearest child
// (the first one on ties). words[i]: the leaf's word; nodes[i] (if nodes is not
// null): the node on the path at depth min(target_depth, leaf depth), the root for
// target_depth <= 0.
void descend_all(const VocabularyTree& tree, const Descriptor* descriptors, std::size_t n, int target_depth,
                 WordId* words, NodeId* nodes);

}  // namespace orbatlas::vocabulary_detail
