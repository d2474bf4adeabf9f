#include "core/vocabulary/kmedians.h"

#include <algorithm>
#include <cmath>
#include <random>

#include "core/common/error.h"
#include "core/vocabulary/bit_majority.h"
#include "core/vocabulary/parallel_chunks.h"
#include "core/vocabulary/vocabulary_tree.h"

namespace orbatlas::vocabulary_detail {
namespace {

constexpr std::uint16_t kUnassigned = 0xFFFF;
// Below this many members a split runs on one thread (the trainer then runs
// several nodes at once instead).
constexpr std::size_t kParallelMembers = 32768;

ORBATLAS_POPCNT_CLONES
void lower_min_distances(const Descriptor* members, std::size_t begin, std::size_t end, const Descriptor& centre,
                         std::uint16_t* min_distance) {
  for (std::size_t i = begin; i < end; ++i) {
    const auto d = static_cast<std::uint16_t>(hamming(members[i], centre));
    if (d < min_distance[i]) min_distance[i] = d;
  }
}

// sums[c] += sum over members of min(current distance, distance to candidate c)^2.
ORBATLAS_POPCNT_CLONES
void candidate_potentials(const Descriptor* members, std::size_t begin, std::size_t end,
                          const std::uint16_t* min_distance, const Descriptor* candidates, std::size_t n_candidates,
                          std::uint64_t* sums) {
  for (std::size_t i = begin; i < end; ++i) {
    const Descriptor& x = members[i];
    for (std::size_t c = 0; c < n_candidates; ++c) {
      const std::uint64_t d =
          std::min<std::uint64_t>(min_distance[i], static_cast<std::uint64_t>(hamming(x, candidates[c])));
      sums[c] += d * d;
    }
  }
}

// Nearest centre of each member (first on ties) and the per-cluster bit counts;
// returns how many labels changed.
ORBATLAS_POPCNT_CLONES
std::size_t assign_members(const Descriptor* members, std::size_t begin, std::size_t end, const Descriptor* centres,
                           std::size_t k, std::uint16_t* labels, BitMajority* counts) {
  std::size_t changed = 0;
  for (std::size_t i = begin; i < end; ++i) {
    const Descriptor& x = members[i];
    std::size_t best = 0;
    int best_distance = hamming(x, centres[0]);
    for (std::size_t j = 1; j < k; ++j) {
      const int d = hamming(x, centres[j]);
      if (d < best_distance) {
        best_distance = d;
        best = j;
      }
    }
    if (labels[i] != best) {
      labels[i] = static_cast<std::uint16_t>(best);
      ++changed;
    }
    counts[best].add(x);
  }
  return changed;
}

struct Pass {
  std::size_t chunks;
  int threads;
};

// Greedy k-means++: centres drawn with probability proportional to D^2, each the
// best (lowest resulting potential) of `trials` candidates.
std::vector<Descriptor> seed_centres(std::span<const Descriptor> members, const KmediansOptions& options,
                                     const Pass& pass, std::mt19937_64& rng) {
  const std::size_t n = members.size();
  const std::size_t trials = 2 + static_cast<std::size_t>(std::log(static_cast<double>(options.k)));
  std::vector<Descriptor> centres;
  centres.push_back(members[rng() % n]);
  std::vector<std::uint16_t> min_distance(n, kUnassigned);
  const auto lower = [&](const Descriptor& centre) {
    run_chunks(n, pass.chunks, pass.threads, [&](std::size_t, std::size_t b, std::size_t e) {
      lower_min_distances(members.data(), b, e, centre, min_distance.data());
    });
  };
  lower(centres[0]);
  std::uint64_t potential = 0;
  for (const std::uint16_t d : min_distance) potential += std::uint64_t{d} * d;

  std::vector<std::uint64_t> thresholds(trials), sums(pass.chunks * trials);
  std::vector<Descriptor> candidates(trials);
  while (centres.size() < static_cast<std::size_t>(options.k) && potential > 0) {
    for (auto& t : thresholds) t = rng() % potential;
    std::sort(thresholds.begin(), thresholds.end());
    std::uint64_t cumulative = 0;
    std::size_t t = 0;
    for (std::size_t i = 0; i < n && t < trials; ++i) {
      cumulative += std::uint64_t{min_distance[i]} * min_distance[i];
      while (t < trials && thresholds[t] < cumulative) candidates[t++] = members[i];
    }
    std::fill(sums.begin(), sums.end(), 0);
    run_chunks(n, pass.chunks, pass.threads, [&](std::size_t c, std::size_t b, std::size_t e) {
      candidate_potentials(members.data(), b, e, min_distance.data(), candidates.data(), trials,
                           sums.data() + c * trials);
    });
    std::size_t best = 0;
    std::uint64_t best_potential = 0;
    for (std::size_t c = 0; c < trials; ++c) {
      std::uint64_t total = 0;
      for (std::size_t chunk = 0; chunk < pass.chunks; ++chunk) total += sums[chunk * trials + c];
      if (c == 0 || total < best_potential) {
        best_potential = total;
        best = c;
      }
    }
    centres.push_back(candidates[best]);
    lower(candidates[best]);
    potential = best_potential;
  }
  return centres;
}

}  // namespace

void KmediansOptions::check() const {
  ORBATLAS_CHECK(k >= 2 && k < kUnassigned, "k-medians: k must be in [2, " << kUnassigned - 1 << "], not " << k);
  ORBATLAS_CHECK(iterations >= 1, "k-medians: iterations must be >= 1, not " << iterations);
  ORBATLAS_CHECK(threads >= 0, "k-medians: threads must be >= 0, not " << threads);
}

KmediansSplit kmedians_split(std::span<Descriptor> members, const KmediansOptions& options,
                             const std::function<void(std::size_t)>& on_work) {
  const std::size_t n = members.size();
  ORBATLAS_CHECK(n > 0, "k-medians needs at least one descriptor");
  options.check();
  const std::size_t chunks =
      (options.threads > 1 && n >= kParallelMembers) ? static_cast<std::size_t>(options.threads) : std::size_t{1};
  const Pass pass{chunks, options.threads};
  std::mt19937_64 rng(options.seed);
  std::vector<Descriptor> centres = seed_centres(members, options, pass, rng);
  const std::size_t k = centres.size();

  std::vector<std::uint16_t> labels(n, kUnassigned);
  std::vector<std::vector<BitMajority>> counts(chunks, std::vector<BitMajority>(k));
  std::vector<std::size_t> changed(chunks);
  std::size_t reported = 0;
  const auto report = [&](std::size_t done) {
    if (on_work && done > reported) on_work(done - reported);
    reported = std::max(reported, done);
  };
  const auto iterations = static_cast<std::size_t>(options.iterations);
  for (std::size_t it = 0; it < iterations; ++it) {
    for (auto& per_chunk : counts)
      for (auto& c : per_chunk) c.clear();
    run_chunks(n, chunks, pass.threads, [&](std::size_t c, std::size_t b, std::size_t e) {
      changed[c] = assign_members(members.data(), b, e, centres.data(), k, labels.data(), counts[c].data());
    });
    for (std::size_t c = 1; c < chunks; ++c)
      for (std::size_t j = 0; j < k; ++j) counts[0][j].merge(counts[c][j]);
    report(n * (it + 1) / iterations);
    std::size_t total_changed = 0;
    for (const std::size_t c : changed) total_changed += c;
    if (total_changed == 0) break;  // the centres are already the medians of these members
    for (std::size_t j = 0; j < k; ++j)
      if (counts[0][j].size() > 0) centres[j] = counts[0][j].majority();
  }
  report(n);

  // Drop empty clusters and group the members by cluster (stable).
  KmediansSplit split;
  std::vector<std::uint16_t> compact(k, kUnassigned);
  for (std::size_t j = 0; j < k; ++j) {
    if (counts[0][j].size() == 0) continue;
    compact[j] = static_cast<std::uint16_t>(split.centres.size());
    split.centres.push_back(centres[j]);
    split.sizes.push_back(counts[0][j].size());
  }
  std::vector<std::size_t> offsets(split.sizes.size(), 0);
  for (std::size_t j = 1; j < offsets.size(); ++j) offsets[j] = offsets[j - 1] + split.sizes[j - 1];
  std::vector<Descriptor> grouped(n);
  for (std::size_t i = 0; i < n; ++i) grouped[offsets[compact[labels[i]]]++] = members[i];
  std::copy(grouped.begin(), grouped.end(), members.begin());
  return split;
}

}  // namespace orbatlas::vocabulary_detail
