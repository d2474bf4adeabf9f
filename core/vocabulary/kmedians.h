#pragma once
// Internal to the vocabulary library: one k-medians split of a vocabulary node.
// Seeding is greedy k-means++ (each new centre is the best of a few candidates drawn
// with probability proportional to the squared distance to the nearest centre);
// iterations assign every descriptor to its nearest centre (Hamming, first on ties)
// and move each centre to the bitwise majority of its members.
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "core/features/descriptor.h"

namespace orbatlas::vocabulary_detail {

struct KmediansOptions {
  int k = 10;
  int iterations = 10;
  std::uint64_t seed = 1;
  int threads = 1;  // for the seeding and assignment passes (worth it for large nodes only)

  // Throws Error naming the first value out of range.
  void check() const;
};

struct KmediansSplit {
  std::vector<Descriptor> centres;   // non-empty clusters only
  std::vector<std::uint32_t> sizes;  // members per cluster
};

// Clusters `members` and reorders them so that each cluster's members are
// contiguous, in the order of the returned centres (the trainer keeps every node's
// descriptors contiguous this way, so all passes read memory sequentially). Gives
// fewer than k clusters when there are fewer distinct descriptors (one cluster if
// they are all equal). on_work(units) is called with a total of members.size()
// units as the iterations go (may be empty). Deterministic for a given seed,
// whatever the number of threads.
KmediansSplit kmedians_split(std::span<Descriptor> members, const KmediansOptions& options,
                             const std::function<void(std::size_t)>& on_work = {});

}  // namespace orbatlas::vocabulary_detail
