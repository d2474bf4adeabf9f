// Vocabulary training: deterministic whatever the number of threads (its hash
// identifies it), edge cases and bad options, large nodes split on several
// threads, and the progress it reports.
#include <gtest/gtest.h>

#include <cstddef>
#include <random>
#include <vector>

#include "core/common/error.h"
#include "core/vocabulary/vocabulary.h"
#include "tests/support/vocabulary_data.h"

namespace orbatlas {
namespace {

using test::ClusteredData;
using test::flip_bits;
using test::make_clustered_data;
using test::random_descriptor;
using test::small_options;
using test::VocabularyTest;

TEST_F(VocabularyTest, HashIdentifiesTheVocabulary) {
  // Training is deterministic, whatever the number of threads.
  VocabularyTrainingOptions one_thread = small_options();
  one_thread.threads = 1;
  VocabularyTrainingOptions three_threads = small_options();
  three_threads.threads = 3;
  EXPECT_EQ(Vocabulary::train(data().images, one_thread).hash(), voc().hash());
  EXPECT_EQ(Vocabulary::train(data().images, three_threads).hash(), voc().hash());
  EXPECT_NE(Vocabulary::train(data().images, small_options(8)).hash(), voc().hash());
}

TEST(VocabularyTraining, EdgeCases) {
  std::mt19937_64 rng(9);
  const Descriptor d = random_descriptor(rng);
  // All descriptors equal: the root is the only word.
  const Vocabulary single = Vocabulary::train({{d, d}, {d}}, small_options());
  EXPECT_EQ(single.word_count(), 1u);
  EXPECT_EQ(single.info().nodes, 1u);
  EXPECT_EQ(single.word_of(random_descriptor(rng)), 0u);
  // Fewer distinct descriptors than k: one word each.
  const Descriptor e = random_descriptor(rng), f = random_descriptor(rng);
  const Vocabulary three = Vocabulary::train({{d, e}, {f, d}, {e}}, small_options());
  EXPECT_EQ(three.word_count(), 3u);
  EXPECT_NE(three.word_of(d), three.word_of(e));
  EXPECT_NE(three.word_of(e), three.word_of(f));

  EXPECT_THROW(Vocabulary::train({}, small_options()), Error);
  EXPECT_THROW(Vocabulary::train({{}, {}}, small_options()), Error);
  VocabularyTrainingOptions bad = small_options();
  bad.k = 1;
  EXPECT_THROW(Vocabulary::train({{d}}, bad), Error);
  bad = small_options();
  bad.levels = 0;
  EXPECT_THROW(Vocabulary::train({{d}}, bad), Error);
}

TEST(VocabularyTraining, LargeNodesGiveTheSameTreeOnAnyNumberOfThreads) {
  // 60,000 descriptors: the root split runs its passes on several threads.
  std::mt19937_64 rng(12);
  std::vector<Descriptor> prototypes(500);
  for (auto& p : prototypes) p = random_descriptor(rng);
  std::vector<std::vector<Descriptor>> images(60);
  for (auto& image : images)
    for (int i = 0; i < 1000; ++i) image.push_back(flip_bits(prototypes[rng() % prototypes.size()], 20, rng));
  VocabularyTrainingOptions o;
  o.k = 10;
  o.levels = 2;
  o.threads = 1;
  const Vocabulary one = Vocabulary::train(images, o);
  o.threads = 2;
  const Vocabulary two = Vocabulary::train(images, o);
  EXPECT_EQ(one.hash(), two.hash());
  EXPECT_EQ(one.word_count(), two.word_count());
  EXPECT_GT(one.word_count(), 50u);
}

TEST(VocabularyTraining, ReportsProgressUpToTheTotal) {
  const ClusteredData data = make_clustered_data(11);
  VocabularyTrainingOptions o = small_options();
  std::size_t last = 0, total = 0, calls = 0;
  bool monotonic = true;
  o.progress = [&](std::size_t done, std::size_t t) {
    monotonic = monotonic && done >= last && (total == 0 || t == total);
    last = done;
    total = t;
    ++calls;
  };
  (void)Vocabulary::train(data.images, o);
  EXPECT_TRUE(monotonic);
  EXPECT_GT(calls, 3u);
  EXPECT_GT(total, 0u);
  EXPECT_EQ(last, total);
}

}  // namespace
}  // namespace orbatlas
