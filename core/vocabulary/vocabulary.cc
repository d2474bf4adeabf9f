// Vocabulary: queries on a trained or loaded tree (training and file I/O live in
// vocabulary_training.cc and vocabulary_io.cc).
#include "core/vocabulary/vocabulary.h"

#include <algorithm>
#include <cmath>

#include "core/common/error.h"
#include "core/vocabulary/vocabulary_impl.h"

namespace orbatlas {

using vocabulary_detail::descend_all;

Vocabulary::Vocabulary() : impl_(std::make_unique<Impl>()) {}
Vocabulary::Vocabulary(Vocabulary&&) noexcept = default;
Vocabulary& Vocabulary::operator=(Vocabulary&&) noexcept = default;
Vocabulary::~Vocabulary() = default;

const VocabularyInfo& Vocabulary::info() const { return impl_->info; }

void Vocabulary::transform(const std::vector<Descriptor>& descriptors, BowVector* bow, FeatureVector* features,
                           int levels_up) const {
  ORBATLAS_CHECK(levels_up >= 0, "Vocabulary::transform: levels_up must be >= 0, got " << levels_up);
  if (bow != nullptr) bow->clear();
  if (features != nullptr) features->clear();
  const std::size_t n = descriptors.size();
  if (n == 0 || (bow == nullptr && features == nullptr)) return;
  const auto& tree = impl_->tree;
  std::vector<WordId> words(n);
  std::vector<NodeId> nodes(features != nullptr ? n : 0);
  descend_all(tree, descriptors.data(), n, tree.levels - levels_up, words.data(),
              features != nullptr ? nodes.data() : nullptr);

  if (bow != nullptr) {
    // TF-IDF: count * idf per word (tf's 1/n cancels in the L1 normalisation).
    // Words of weight 0 (in every training image) are left out, as in DBoW2.
    std::vector<WordId> sorted = words;
    std::sort(sorted.begin(), sorted.end());
    double total = 0.0;
    for (std::size_t i = 0; i < n;) {
      std::size_t j = i + 1;
      while (j < n && sorted[j] == sorted[i]) ++j;
      const double value = tree.word_weights[sorted[i]] * static_cast<double>(j - i);
      if (value > 0.0) {
        bow->emplace_hint(bow->end(), sorted[i], value);
        total += value;
      }
      i = j;
    }
    if (total > 0.0)
      for (auto& entry : *bow) entry.second /= total;
  }
  if (features != nullptr) {
    std::vector<std::pair<NodeId, std::uint32_t>> by_node;
    by_node.reserve(n);
    for (std::size_t i = 0; i < n; ++i)
      if (tree.word_weights[words[i]] > 0.0) by_node.emplace_back(nodes[i], static_cast<std::uint32_t>(i));
    std::sort(by_node.begin(), by_node.end());
    for (std::size_t i = 0; i < by_node.size();) {
      std::size_t j = i + 1;
      while (j < by_node.size() && by_node[j].first == by_node[i].first) ++j;
      auto& indices = features->emplace_hint(features->end(), by_node[i].first, std::vector<std::uint32_t>())->second;
      indices.reserve(j - i);
      for (std::size_t m = i; m < j; ++m) indices.push_back(by_node[m].second);
      i = j;
    }
  }
}

WordId Vocabulary::word_of(const Descriptor& d) const {
  WordId word = 0;
  descend_all(impl_->tree, &d, 1, 0, &word, nullptr);
  return word;
}

double Vocabulary::word_weight(WordId w) const {
  ORBATLAS_CHECK(w < impl_->tree.word_weights.size(),
                 "word " << w << " out of range (" << impl_->tree.word_weights.size() << " words)");
  return impl_->tree.word_weights[w];
}

double Vocabulary::score(const BowVector& a, const BowVector& b) {
  // 1 - 0.5 |a - b|_1 = 0.5 * sum over shared words of (|a_i| + |b_i| - |a_i - b_i|)
  // for L1-normalised vectors (DBoW2's form: only shared words contribute).
  double sum = 0.0;
  auto ia = a.begin(), ib = b.begin();
  while (ia != a.end() && ib != b.end()) {
    if (ia->first < ib->first) {
      ia = a.lower_bound(ib->first);
    } else if (ib->first < ia->first) {
      ib = b.lower_bound(ia->first);
    } else {
      sum += std::abs(ia->second) + std::abs(ib->second) - std::abs(ia->second - ib->second);
      ++ia;
      ++ib;
    }
  }
  return 0.5 * sum;
}

const Descriptor& Vocabulary::node_descriptor(NodeId node) const {
  ORBATLAS_CHECK(node < impl_->tree.node_count(),
                 "node " << node << " out of range (" << impl_->tree.node_count() << " nodes)");
  return impl_->tree.descriptors[node];
}

NodeId Vocabulary::node_parent(NodeId node) const {
  ORBATLAS_CHECK(node < impl_->tree.node_count(),
                 "node " << node << " out of range (" << impl_->tree.node_count() << " nodes)");
  return impl_->tree.parents[node];
}

std::pair<NodeId, std::uint32_t> Vocabulary::node_children(NodeId node) const {
  ORBATLAS_CHECK(node < impl_->tree.node_count(),
                 "node " << node << " out of range (" << impl_->tree.node_count() << " nodes)");
  return {impl_->tree.first_child[node], impl_->tree.child_count[node]};
}

NodeId Vocabulary::word_node(WordId word) const {
  ORBATLAS_CHECK(word < impl_->tree.word_nodes.size(),
                 "word " << word << " out of range (" << impl_->tree.word_nodes.size() << " words)");
  return impl_->tree.word_nodes[word];
}

}  // namespace orbatlas
