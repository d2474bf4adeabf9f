#include "core/map/keyframe_index.h"

namespace orbatlas {

void KeyframeIndex::add(const std::shared_ptr<KeyFrame>& keyframe) {
  if (!keyframe || keyframe->bow().empty() || keyframe->is_bad()) return;
  std::lock_guard lock(mutex_);
  database_.add(keyframe->id(), keyframe->bow());
  keyframes_[keyframe->id()] = keyframe;
}

void KeyframeIndex::erase(KeyframeId id) {
  std::lock_guard lock(mutex_);
  database_.erase(id);
  keyframes_.erase(id);
}

std::size_t KeyframeIndex::size() const {
  std::lock_guard lock(mutex_);
  return keyframes_.size();
}

std::vector<IndexCandidate> KeyframeIndex::query(const BowVector& bow, std::size_t max_results,
                                                 const std::unordered_set<KeyframeId>& exclude,
                                                 const Filter& accept) const {
  std::vector<IndexCandidate> out;
  std::lock_guard lock(mutex_);
  // Ask for a few more than needed: some may have been culled meanwhile (with
  // a filter: for every scored keyframe).
  const std::size_t ask = accept ? keyframes_.size() : max_results + 8;
  for (const auto& match : database_.query(bow, ask, exclude)) {
    const auto it = keyframes_.find(match.keyframe);
    if (it == keyframes_.end()) continue;
    auto kf = it->second.lock();
    if (!kf || kf->is_bad()) continue;
    if (accept && !accept(*kf)) continue;
    out.push_back({std::move(kf), match.score});
    if (out.size() >= max_results) break;
  }
  return out;
}

}  // namespace orbatlas
