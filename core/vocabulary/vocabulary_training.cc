// Vocabulary::train: hierarchical k-medians, level by level, then IDF weights.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <mutex>
#include <thread>

#include "core/common/error.h"
#include "core/vocabulary/kmedians.h"
#include "core/vocabulary/parallel_chunks.h"
#include "core/vocabulary/vocabulary_impl.h"

namespace orbatlas {
namespace {

using vocabulary_detail::KmediansSplit;
using vocabulary_detail::VocabularyTree;

// Nodes with at least this many members are split one at a time with all threads
// inside the split; smaller ones are split several at once, one per thread.
constexpr std::size_t kLargeNode = 32768;

// Forwards (done, total) to the caller's callback, from any thread, in order.
class ProgressReporter {
 public:
  ProgressReporter(std::size_t total, const std::function<void(std::size_t, std::size_t)>& callback)
      : total_(total), callback_(callback) {}
  void add(std::size_t units) {
    if (!callback_ || units == 0) return;
    const std::lock_guard lock(mutex_);
    done_ = std::min(total_, done_ + units);
    callback_(done_, total_);
  }

 private:
  std::size_t total_, done_ = 0;
  const std::function<void(std::size_t, std::size_t)>& callback_;
  std::mutex mutex_;
};

std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

// A node still to split: its members are working[begin, end).
struct PendingNode {
  NodeId node;
  std::uint32_t begin, end;
  std::uint32_t size() const { return end - begin; }
};

// Splits every pending node of one level; returns the splits in the same order.
std::vector<KmediansSplit> split_level(std::vector<Descriptor>& working, const std::vector<PendingNode>& pending,
                                       const VocabularyTrainingOptions& o, int threads, ProgressReporter& progress) {
  std::vector<KmediansSplit> splits(pending.size());
  const auto split = [&](std::size_t i, int inner_threads) {
    const PendingNode& p = pending[i];
    vocabulary_detail::KmediansOptions ko;
    ko.k = o.k;
    ko.iterations = o.kmedians_iterations;
    ko.seed = splitmix64(o.seed ^ splitmix64(p.node));
    ko.threads = inner_threads;
    splits[i] = vocabulary_detail::kmedians_split(std::span(working).subspan(p.begin, p.size()), ko,
                                                  [&](std::size_t units) { progress.add(units); });
  };
  std::vector<std::size_t> small;
  for (std::size_t i = 0; i < pending.size(); ++i) {
    if (pending[i].size() >= kLargeNode)
      split(i, threads);
    else
      small.push_back(i);
  }
  vocabulary_detail::run_chunks(small.size(), small.size(), threads, [&](std::size_t, std::size_t b, std::size_t e) {
    for (std::size_t s = b; s < e; ++s) split(small[s], 1);
  });
  return splits;
}

// word -> number of training images in which it occurs.
std::vector<std::uint32_t> images_per_word(const VocabularyTree& tree,
                                           const std::vector<std::vector<Descriptor>>& per_image, int threads,
                                           ProgressReporter& progress) {
  const std::size_t n_words = tree.word_nodes.size(), n_images = per_image.size();
  const std::size_t chunks =
      std::min<std::size_t>(static_cast<std::size_t>(threads), std::max<std::size_t>(n_images, 1));
  std::vector<std::vector<std::uint32_t>> partial(chunks);
  vocabulary_detail::run_chunks(n_images, chunks, threads, [&](std::size_t c, std::size_t b, std::size_t e) {
    std::vector<std::uint32_t> counts(n_words, 0);
    std::vector<std::size_t> last_image(n_words, n_images);  // counts each word once per image
    std::vector<WordId> words;
    for (std::size_t image = b; image < e; ++image) {
      const auto& descriptors = per_image[image];
      words.resize(descriptors.size());
      vocabulary_detail::descend_all(tree, descriptors.data(), descriptors.size(), 0, words.data(), nullptr);
      for (const WordId w : words) {
        if (last_image[w] == image) continue;
        last_image[w] = image;
        ++counts[w];
      }
      progress.add(descriptors.size());
    }
    partial[c] = std::move(counts);
  });
  std::vector<std::uint32_t> total(n_words, 0);
  for (const auto& counts : partial)
    for (std::size_t w = 0; w < counts.size(); ++w) total[w] += counts[w];
  return total;
}

}  // namespace

void VocabularyTrainingOptions::check() const {
  ORBATLAS_CHECK(k >= 2 && k <= 1000, "vocabulary training: k must be in [2, 1000], got " << k);
  ORBATLAS_CHECK(levels >= 1 && levels <= 16, "vocabulary training: levels must be in [1, 16], got " << levels);
  ORBATLAS_CHECK(kmedians_iterations >= 1,
                 "vocabulary training: kmedians_iterations must be >= 1, got " << kmedians_iterations);
  ORBATLAS_CHECK(threads >= 0, "vocabulary training: threads must be >= 0, got " << threads);
}

Vocabulary Vocabulary::train(const std::vector<std::vector<Descriptor>>& descriptors_per_image,
                             const VocabularyTrainingOptions& options) {
  options.check();
  // All descriptors in one array that the splits reorder, node by node.
  std::vector<Descriptor> working;
  for (const auto& image : descriptors_per_image) working.insert(working.end(), image.begin(), image.end());
  const std::size_t n = working.size();
  ORBATLAS_CHECK(n > 0, "vocabulary training: no descriptors in " << descriptors_per_image.size() << " images");
  ORBATLAS_CHECK(n < std::numeric_limits<std::uint32_t>::max(),
                 "vocabulary training: too many descriptors (" << n << ")");
  const int threads =
      options.threads > 0 ? options.threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  const auto levels = static_cast<std::size_t>(options.levels);
  ProgressReporter progress(n * levels + n, options.progress);

  Vocabulary vocabulary;
  VocabularyTree& tree = vocabulary.impl_->tree;
  tree.k = options.k;
  tree.levels = options.levels;
  tree.descriptors.assign(1, Descriptor{});
  tree.first_child.assign(1, 0);
  tree.child_count.assign(1, 0);

  std::vector<PendingNode> pending{{0, 0, static_cast<std::uint32_t>(n)}};
  for (std::size_t depth = 0; depth < levels && !pending.empty(); ++depth) {
    const std::vector<KmediansSplit> splits = split_level(working, pending, options, threads, progress);
    // Children get consecutive ids in the order of their parents: breadth-first,
    // deterministic whatever the thread scheduling.
    std::vector<PendingNode> next;
    for (std::size_t i = 0; i < pending.size(); ++i) {
      const PendingNode& p = pending[i];
      const KmediansSplit& s = splits[i];
      if (s.centres.size() < 2) {  // all members equal: a word above the last level
        progress.add(std::size_t{p.size()} * (levels - depth - 1));
        continue;
      }
      ORBATLAS_CHECK(tree.node_count() + s.centres.size() < std::numeric_limits<NodeId>::max(),
                     "vocabulary training: too many nodes");
      tree.first_child[p.node] = static_cast<std::uint32_t>(tree.node_count());
      tree.child_count[p.node] = static_cast<std::uint32_t>(s.centres.size());
      std::uint32_t begin = p.begin;
      for (std::size_t c = 0; c < s.centres.size(); ++c) {
        const auto child = static_cast<NodeId>(tree.node_count());
        tree.descriptors.push_back(s.centres[c]);
        tree.first_child.push_back(0);
        tree.child_count.push_back(0);
        if (depth + 1 < levels) next.push_back({child, begin, begin + s.sizes[c]});
        begin += s.sizes[c];
      }
    }
    pending = std::move(next);
  }

  for (std::size_t i = 0; i < tree.node_count(); ++i)
    if (tree.child_count[i] == 0) tree.word_nodes.push_back(static_cast<NodeId>(i));
  tree.word_weights.assign(tree.word_nodes.size(), 0.0);
  tree.derive_and_check();

  // IDF: log(N / n_w) over the training images, measured by transforming them with
  // the finished tree (what queries will see). A word no training image reaches
  // (possible when a member drifts to another cluster) gets the rarest weight, log N.
  const std::vector<std::uint32_t> containing = images_per_word(tree, descriptors_per_image, threads, progress);
  const auto n_images = static_cast<double>(descriptors_per_image.size());
  for (std::size_t w = 0; w < containing.size(); ++w)
    tree.word_weights[w] = std::log(n_images / static_cast<double>(std::max<std::uint32_t>(containing[w], 1)));

  VocabularyInfo& info = vocabulary.impl_->info;
  info.k = tree.k;
  info.levels = tree.levels;
  info.words = tree.word_nodes.size();
  info.nodes = tree.node_count();
  info.training_images = descriptors_per_image.size();
  info.training_descriptors = n;
  info.hash = vocabulary_detail::content_hash(vocabulary_detail::encode_body(tree, info));
  return vocabulary;
}

}  // namespace orbatlas
