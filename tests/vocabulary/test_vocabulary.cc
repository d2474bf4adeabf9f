// The vocabulary tree on synthetic descriptors with a known cluster structure:
// the tree's words, idf weights, the tf-idf transform and its direct index, L1
// scores. Its files are in test_vocabulary_files.cc, training in
// test_vocabulary_training.cc, the KeyframeDatabase in test_keyframe_database.cc.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <set>
#include <vector>

#include "core/common/error.h"
#include "core/vocabulary/vocabulary.h"
#include "tests/support/vocabulary_data.h"

namespace orbatlas {
namespace {

using test::member_of;
using test::random_descriptor;
using test::VocabularyTest;

double l1_norm(const BowVector& v) {
  double s = 0;
  for (const auto& [w, x] : v) s += std::abs(x);
  return s;
}

// 1 - 0.5 |a - b|_1 written out over the union of words.
double reference_score(const BowVector& a, const BowVector& b) {
  std::set<WordId> words;
  for (const auto& [w, x] : a) words.insert(w);
  for (const auto& [w, x] : b) words.insert(w);
  double d = 0;
  for (const WordId w : words) {
    const double xa = a.contains(w) ? a.at(w) : 0.0, xb = b.contains(w) ? b.at(w) : 0.0;
    d += std::abs(xa - xb);
  }
  return 1.0 - 0.5 * d;
}

TEST_F(VocabularyTest, InfoDescribesTheTree) {
  const VocabularyInfo& info = voc().info();
  EXPECT_EQ(info.k, 5);
  EXPECT_EQ(info.levels, 3);
  EXPECT_EQ(info.weighting, "tf-idf");
  EXPECT_EQ(info.scoring, "l1");
  EXPECT_EQ(info.descriptor, "orb-256");
  EXPECT_EQ(info.training_images, 50u);
  EXPECT_EQ(info.training_descriptors, 50u * 62u);
  EXPECT_EQ(info.hash.size(), 16u);
  EXPECT_EQ(voc().word_count(), info.words);
  EXPECT_LE(info.words, 125u);
  EXPECT_GT(info.nodes, info.words);
  // Leaves are exactly the words, in node order.
  std::size_t leaves = 0;
  for (NodeId n = 0; n < info.nodes; ++n)
    if (voc().node_children(n).second == 0) {
      EXPECT_EQ(voc().word_node(static_cast<WordId>(leaves)), n);
      ++leaves;
    }
  EXPECT_EQ(leaves, info.words);
  EXPECT_THROW(voc().node_descriptor(static_cast<NodeId>(info.nodes)), Error);
  EXPECT_THROW(voc().word_weight(static_cast<WordId>(info.words)), Error);
}

TEST_F(VocabularyTest, ClustersMapToTheirOwnWord) {
  std::mt19937_64 rng(3);
  std::set<WordId> cluster_words;
  for (std::size_t c = 0; c < data().centres.size(); ++c) {
    ASSERT_FALSE(data().members[c].empty());
    const WordId word = voc().word_of(data().members[c][0]);
    for (const Descriptor& m : data().members[c]) EXPECT_EQ(voc().word_of(m), word) << "cluster " << c;
    for (int i = 0; i < 20; ++i) EXPECT_EQ(voc().word_of(member_of(data().centres[c], rng)), word) << "cluster " << c;
    EXPECT_EQ(voc().word_of(data().centres[c]), word) << "cluster " << c;
    cluster_words.insert(word);
  }
  // The tree recovers the structure exactly: one word per cluster.
  EXPECT_EQ(cluster_words.size(), data().centres.size());
  EXPECT_EQ(voc().word_count(), data().centres.size());
}

TEST_F(VocabularyTest, WordIsTheNearestChildAtEveryLevel) {
  std::mt19937_64 rng(4);
  std::vector<Descriptor> queries;
  for (int i = 0; i < 1000; ++i) queries.push_back(random_descriptor(rng));
  for (int i = 0; i < 200; ++i) queries.push_back(member_of(data().centres[rng() % data().centres.size()], rng));
  for (const Descriptor& d : queries) {
    const WordId word = voc().word_of(d);
    NodeId node = voc().word_node(word);
    ASSERT_EQ(voc().node_children(node).second, 0u);
    int depth = 0;
    while (node != 0) {
      const NodeId parent = voc().node_parent(node);
      const auto [first, count] = voc().node_children(parent);
      ASSERT_GE(node, first);
      ASSERT_LT(node, first + count);
      const int chosen = hamming(d, voc().node_descriptor(node));
      for (NodeId c = first; c < first + count; ++c) {
        const int other = hamming(d, voc().node_descriptor(c));
        EXPECT_LE(chosen, other);
        if (c < node) {
          EXPECT_LT(chosen, other) << "ties go to the first child";
        }
      }
      node = parent;
      ++depth;
    }
    EXPECT_LE(depth, 3);
  }
}

TEST_F(VocabularyTest, IdfWeights) {
  // Cluster 0 is in every training image: weight log(50 / 50) = 0.
  const WordId common = voc().word_of(data().centres[0]);
  EXPECT_EQ(voc().word_weight(common), 0.0);
  for (std::size_t c = 1; c < data().centres.size(); ++c) {
    std::size_t images = 0;
    for (const auto& labels : data().image_clusters)
      if (std::find(labels.begin(), labels.end(), c) != labels.end()) ++images;
    EXPECT_NEAR(voc().word_weight(voc().word_of(data().centres[c])), std::log(50.0 / static_cast<double>(images)),
                1e-12)
        << "cluster " << c;
  }
}

TEST_F(VocabularyTest, TransformGivesAnL1NormalisedTfIdfVector) {
  const std::vector<Descriptor>& image = data().images[5];
  BowVector bow;
  FeatureVector features;
  voc().transform(image, &bow, &features, 1);
  EXPECT_NEAR(l1_norm(bow), 1.0, 1e-12);
  // tf-idf by hand: count * idf, normalised; the common word (idf 0) is left out.
  std::map<WordId, double> expected;
  double total = 0;
  for (const Descriptor& d : image) {
    const WordId w = voc().word_of(d);
    if (voc().word_weight(w) > 0) {
      expected[w] += voc().word_weight(w) / static_cast<double>(image.size());
      total += voc().word_weight(w) / static_cast<double>(image.size());
    }
  }
  ASSERT_EQ(bow.size(), expected.size());
  for (const auto& [w, x] : expected) EXPECT_NEAR(bow.at(w), x / total, 1e-12) << "word " << w;
  EXPECT_FALSE(bow.contains(voc().word_of(data().centres[0])));

  // Direct index one level above the leaves: every kept feature once, under an
  // ancestor of its word at depth 2.
  std::set<std::uint32_t> seen;
  for (const auto& [node, indices] : features) {
    for (const std::uint32_t i : indices) {
      EXPECT_TRUE(seen.insert(i).second);
      NodeId n = voc().word_node(voc().word_of(image[i]));
      int depth = 0;
      for (NodeId up = n; up != 0; up = voc().node_parent(up)) ++depth;
      while (depth > 2) {
        n = voc().node_parent(n);
        --depth;
      }
      EXPECT_EQ(node, n);
    }
  }
  std::size_t kept = 0;
  for (const Descriptor& d : image) kept += voc().word_weight(voc().word_of(d)) > 0 ? 1 : 0;
  EXPECT_EQ(seen.size(), kept);

  // levels_up beyond the depth puts everything under the root.
  voc().transform(image, nullptr, &features, 10);
  ASSERT_EQ(features.size(), 1u);
  EXPECT_EQ(features.begin()->first, 0u);
  voc().transform({}, &bow, &features);
  EXPECT_TRUE(bow.empty());
  EXPECT_TRUE(features.empty());
  EXPECT_THROW(voc().transform(image, &bow, nullptr, -1), Error);
}

TEST_F(VocabularyTest, L1Score) {
  BowVector a, b;
  voc().transform(data().images[0], &a, nullptr);
  voc().transform(data().images[4], &b, nullptr);  // shares clusters with image 0
  EXPECT_NEAR(Vocabulary::score(a, a), 1.0, 1e-12);
  EXPECT_DOUBLE_EQ(Vocabulary::score(a, b), Vocabulary::score(b, a));
  EXPECT_NEAR(Vocabulary::score(a, b), reference_score(a, b), 1e-12);
  EXPECT_GT(Vocabulary::score(a, b), 0.0);
  EXPECT_LT(Vocabulary::score(a, b), 1.0);
  const BowVector x{{1, 0.5}, {3, 0.5}}, y{{2, 0.25}, {4, 0.75}}, z{{1, 0.25}, {2, 0.75}};
  EXPECT_EQ(Vocabulary::score(x, y), 0.0);
  EXPECT_DOUBLE_EQ(Vocabulary::score(x, z), 0.25);
  EXPECT_DOUBLE_EQ(Vocabulary::score(x, z), reference_score(x, z));
  EXPECT_EQ(Vocabulary::score(x, BowVector{}), 0.0);
  for (std::size_t i = 0; i < 10; ++i) {
    BowVector p, q;
    voc().transform(data().images[i], &p, nullptr);
    voc().transform(data().images[(i + 3) % data().images.size()], &q, nullptr);
    EXPECT_NEAR(Vocabulary::score(p, q), reference_score(p, q), 1e-12);
  }
}

}  // namespace
}  // namespace orbatlas
