#include "core/vocabulary/vocabulary_tree.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "core/common/error.h"

namespace orbatlas::vocabulary_detail {

void VocabularyTree::derive_and_check() {
  const std::size_t n = descriptors.size();
  ORBATLAS_CHECK(k >= 2 && levels >= 1 && levels <= 255, "invalid tree shape k = " << k << ", levels = " << levels);
  ORBATLAS_CHECK(
      n >= 1 && first_child.size() == n && child_count.size() == n,
      "node arrays have inconsistent sizes (" << n << ", " << first_child.size() << ", " << child_count.size() << ")");
  ORBATLAS_CHECK(word_weights.size() == word_nodes.size(), "word arrays have inconsistent sizes");
  ORBATLAS_CHECK(n < std::numeric_limits<NodeId>::max(), "too many nodes (" << n << ")");
  parents.assign(n, 0);
  depths.assign(n, 0);
  std::vector<std::uint8_t> has_parent(n, 0);
  has_parent[0] = 1;
  // Children always have larger ids than their parent, so one pass in id order
  // sees every parent before its children and the structure cannot cycle.
  for (std::size_t i = 0; i < n; ++i) {
    ORBATLAS_CHECK(has_parent[i], "node " << i << " is not reachable from the root");
    const std::uint32_t first = first_child[i], count = child_count[i];
    if (count == 0) continue;
    ORBATLAS_CHECK(count <= static_cast<std::uint32_t>(k), "node " << i << " has " << count << " children, k is " << k);
    ORBATLAS_CHECK(first > i && static_cast<std::size_t>(first) + count <= n,
                   "node " << i << " has an invalid child range [" << first << ", " << first + count << ")");
    ORBATLAS_CHECK(depths[i] < levels, "node " << i << " is deeper than " << levels << " levels");
    for (std::uint32_t c = first; c < first + count; ++c) {
      ORBATLAS_CHECK(!has_parent[c], "node " << c << " has two parents");
      has_parent[c] = 1;
      parents[c] = static_cast<NodeId>(i);
      depths[c] = static_cast<std::uint8_t>(depths[i] + 1);
    }
  }
  node_words.assign(n, kNoWord);
  std::size_t next_word = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (child_count[i] != 0) continue;
    ORBATLAS_CHECK(next_word < word_nodes.size() && word_nodes[next_word] == i,
                   "leaf " << i << " is not word " << next_word << " (words must be the leaves in node order)");
    node_words[i] = static_cast<WordId>(next_word++);
  }
  ORBATLAS_CHECK(next_word == word_nodes.size(),
                 "there are " << word_nodes.size() << " words but " << next_word << " leaves");
  for (std::size_t w = 0; w < word_weights.size(); ++w)
    ORBATLAS_CHECK(std::isfinite(word_weights[w]) && word_weights[w] >= 0.0,
                   "word " << w << " has an invalid weight " << word_weights[w]);
}

// Descriptors go down in batches, level by level in lockstep: the children of all
// the batch's current nodes are prefetched before any is compared, so the cache
// misses of the lower levels (the tree is a few MB) overlap instead of queueing.
ORBATLAS_POPCNT_CLONES
void descend_all(const VocabularyTree& tree, const Descriptor* descriptors, std::size_t n, int target_depth,
                 WordId* words, NodeId* nodes) {
  constexpr std::size_t kBatch = 16;
  const Descriptor* centres = tree.descriptors.data();
  const std::uint32_t* first_child = tree.first_child.data();
  const std::uint32_t* child_count = tree.child_count.data();
  for (std::size_t b0 = 0; b0 < n; b0 += kBatch) {
    const std::size_t m = std::min(kBatch, n - b0);
    const Descriptor* batch = descriptors + b0;
    std::array<NodeId, kBatch> node{}, at_target{};
    for (int depth = 1;; ++depth) {
      for (std::size_t i = 0; i < m; ++i) {
        const std::uint32_t count = child_count[node[i]];
        const char* block = reinterpret_cast<const char*>(centres + first_child[node[i]]);
        for (std::size_t offset = 0; offset < count * sizeof(Descriptor); offset += 64)
          __builtin_prefetch(block + offset);
      }
      bool moved = false;
      for (std::size_t i = 0; i < m; ++i) {
        const std::uint32_t count = child_count[node[i]];
        if (count == 0) continue;
        const std::uint32_t first = first_child[node[i]], end = first + count;
        NodeId best = first;
        int best_distance = hamming(batch[i], centres[first]);
        for (std::uint32_t c = first + 1; c < end; ++c) {
          const int distance = hamming(batch[i], centres[c]);
          if (distance < best_distance) {
            best_distance = distance;
            best = c;
          }
        }
        node[i] = best;
        if (depth <= target_depth) at_target[i] = best;
        __builtin_prefetch(child_count + best);
        __builtin_prefetch(first_child + best);
        moved = true;
      }
      if (!moved) break;
    }
    for (std::size_t i = 0; i < m; ++i) {
      words[b0 + i] = tree.node_words[node[i]];
      if (nodes != nullptr) nodes[b0 + i] = at_target[i];
    }
  }
}

}  // namespace orbatlas::vocabulary_detail
