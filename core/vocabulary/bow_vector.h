#pragma once
// Bag-of-words representations of one image.
#include <cstdint>
#include <map>
#include <vector>

namespace orbatlas {

using WordId = std::uint32_t;
using NodeId = std::uint32_t;

// Word -> weight (TF-IDF), L1-normalised; ordered by word id for merge-style scoring.
using BowVector = std::map<WordId, double>;

// Direct index: vocabulary node at the chosen level -> indices of the image's
// features under it. Matching only compares features sharing a node.
using FeatureVector = std::map<NodeId, std::vector<std::uint32_t>>;

// Calls fn(features_of_a, features_of_b) for every node both direct indexes hold,
// in node order (a merge walk that skips ahead with lower_bound).
template <class Fn>
void for_each_common_node(const FeatureVector& a, const FeatureVector& b, Fn&& fn) {
  auto ia = a.begin();
  auto ib = b.begin();
  while (ia != a.end() && ib != b.end()) {
    if (ia->first < ib->first) {
      ia = a.lower_bound(ib->first);
    } else if (ib->first < ia->first) {
      ib = b.lower_bound(ia->first);
    } else {
      fn(ia->second, ib->second);
      ++ia;
      ++ib;
    }
  }
}

}  // namespace orbatlas
