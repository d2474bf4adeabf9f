#pragma once
// Inverted index from words to the keyframes that contain them, shared later by
// relocalization, loop closing and map merging. Keyframes are plain 64-bit ids.
#include <cstdint>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "core/common/ids.h"
#include "core/vocabulary/bow_vector.h"

namespace orbatlas {

struct DatabaseMatch {
  KeyframeId keyframe = 0;
  double score = 0.0;
};

class KeyframeDatabase {
 public:
  void add(KeyframeId id, const BowVector& bow);  // replaces an existing entry with the same id
  void erase(KeyframeId id);                      // no-op if absent
  std::size_t size() const { return bows_.size(); }

  // Best `max_results` keyframes by L1 score among those sharing at least one
  // word with `query`, excluding `exclude`; best first.
  std::vector<DatabaseMatch> query(const BowVector& query, std::size_t max_results,
                                   const std::unordered_set<KeyframeId>& exclude = {}) const;

 private:
  // A keyframe in a word's inverted list, with its weight for that word, so that
  // query() accumulates the L1 score over the lists without looking up the vectors.
  struct Posting {
    KeyframeId keyframe = 0;
    double weight = 0.0;
  };
  std::unordered_map<WordId, std::vector<Posting>> inverted_;
  std::unordered_map<KeyframeId, BowVector> bows_;
};

}  // namespace orbatlas
