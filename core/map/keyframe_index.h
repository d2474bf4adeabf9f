#pragma once
// The place-recognition index over every map of an atlas: the bag-of-words
// inverted file (KeyframeDatabase) plus weak links to the keyframes, guarded by a
// mutex so that local mapping can add and remove keyframes while tracking (and
// later loop closing) queries it. Culled keyframes are erased by whoever culls
// them; a keyframe freed before that is skipped by queries.
#include <functional>
#include <memory>
#include <mutex>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "core/map/keyframe.h"
#include "core/vocabulary/keyframe_database.h"

namespace orbatlas {

struct IndexCandidate {
  std::shared_ptr<KeyFrame> keyframe;
  double score = 0.0;
};

class KeyframeIndex {
 public:
  void add(const std::shared_ptr<KeyFrame>& keyframe);  // indexes keyframe->bow(); no-op when empty
  void erase(KeyframeId id);
  std::size_t size() const;

  // Live keyframes by L1 score, best first, at most max_results. With
  // `accept`, only keyframes it accepts count (e.g. those of other maps), so
  // that others scoring higher cannot crowd them out.
  using Filter = std::function<bool(const KeyFrame&)>;
  std::vector<IndexCandidate> query(const BowVector& bow, std::size_t max_results,
                                    const std::unordered_set<KeyframeId>& exclude = {},
                                    const Filter& accept = {}) const;

 private:
  mutable std::mutex mutex_;
  KeyframeDatabase database_;
  std::unordered_map<KeyframeId, std::weak_ptr<KeyFrame>> keyframes_;
};

}  // namespace orbatlas
