#include "core/vocabulary/keyframe_database.h"

#include <algorithm>
#include <cmath>

namespace orbatlas {

void KeyframeDatabase::add(KeyframeId id, const BowVector& bow) {
  erase(id);
  bows_.emplace(id, bow);
  for (const auto& [word, weight] : bow) inverted_[word].push_back({id, weight});
}

void KeyframeDatabase::erase(KeyframeId id) {
  const auto it = bows_.find(id);
  if (it == bows_.end()) return;
  for (const auto& entry : it->second) {
    const auto list = inverted_.find(entry.first);
    if (list == inverted_.end()) continue;
    auto& postings = list->second;
    const auto pos =
        std::find_if(postings.begin(), postings.end(), [id](const Posting& p) { return p.keyframe == id; });
    if (pos != postings.end()) {
      *pos = postings.back();  // order within a list does not matter
      postings.pop_back();
    }
    if (postings.empty()) inverted_.erase(list);
  }
  bows_.erase(it);
}

std::vector<DatabaseMatch> KeyframeDatabase::query(const BowVector& query, std::size_t max_results,
                                                   const std::unordered_set<KeyframeId>& exclude) const {
  // L1 score 1 - 0.5 |q - v|_1 = 0.5 * sum over shared words of (|q_w| + |v_w| - |q_w - v_w|)
  // for L1-normalised vectors: accumulated over the inverted lists of the query's
  // words, so only keyframes sharing a word are touched. Each keyframe receives its
  // terms in word order, as in Vocabulary::score, so the sums are the same doubles.
  std::unordered_map<KeyframeId, double> sums;
  for (const auto& [word, q] : query) {
    const auto list = inverted_.find(word);
    if (list == inverted_.end()) continue;
    for (const Posting& p : list->second) sums[p.keyframe] += std::abs(q) + std::abs(p.weight) - std::abs(q - p.weight);
  }
  std::vector<DatabaseMatch> matches;
  matches.reserve(sums.size());
  for (const auto& [id, sum] : sums)
    if (!exclude.contains(id)) matches.push_back({id, 0.5 * sum});
  // Best first; equal scores by smaller id, so results do not depend on hashing.
  const auto better = [](const DatabaseMatch& a, const DatabaseMatch& b) {
    return a.score != b.score ? a.score > b.score : a.keyframe < b.keyframe;
  };
  const std::size_t keep = std::min(max_results, matches.size());
  std::partial_sort(matches.begin(), matches.begin() + static_cast<std::ptrdiff_t>(keep), matches.end(), better);
  matches.resize(keep);
  return matches;
}

}  // namespace orbatlas
