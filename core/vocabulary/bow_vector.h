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

}  // namespace orbatlas
