// Vocabulary (training, transform, scoring, file format) and KeyframeDatabase,
// on synthetic descriptors with a known cluster structure.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <random>
#include <set>
#include <string>

#include "core/common/error.h"
#include "core/vocabulary/keyframe_database.h"
#include "core/vocabulary/vocabulary.h"

namespace orbatlas {
namespace {

namespace fs = std::filesystem;

Descriptor random_descriptor(std::mt19937_64& rng) { return {rng(), rng(), rng(), rng()}; }

// Flips `n` distinct random bits.
Descriptor flip_bits(Descriptor d, int n, std::mt19937_64& rng) {
  std::set<int> bits;
  while (static_cast<int>(bits.size()) < n) bits.insert(static_cast<int>(rng() % 256));
  for (const int b : bits) d[b / 64] ^= std::uint64_t{1} << (b % 64);
  return d;
}

// 125 cluster centres built as a tree that matches k = 5, L = 3: 5 random group
// prototypes, 5 subgroups per group (32 bits flipped), 5 centres per subgroup (12
// bits flipped). Members are a centre with up to 3 bits flipped.
struct ClusteredData {
  std::vector<Descriptor> centres;
  std::vector<std::vector<Descriptor>> images;           // training descriptors per image
  std::vector<std::vector<std::size_t>> image_clusters;  // cluster of each of them
  std::vector<std::vector<Descriptor>> members;          // per cluster, the training members
};

Descriptor member_of(const Descriptor& centre, std::mt19937_64& rng) {
  return flip_bits(centre, static_cast<int>(rng() % 4), rng);
}

// Cluster 0 occurs in every image; the others in about 12 of the 50 images each.
ClusteredData make_clustered_data(std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  ClusteredData data;
  for (int g = 0; g < 5; ++g) {
    const Descriptor group = random_descriptor(rng);
    for (int s = 0; s < 5; ++s) {
      const Descriptor sub = flip_bits(group, 32, rng);
      for (int c = 0; c < 5; ++c) data.centres.push_back(flip_bits(sub, 12, rng));
    }
  }
  const std::size_t n_clusters = data.centres.size(), n_images = 50;
  data.members.resize(n_clusters);
  for (std::size_t i = 0; i < n_images; ++i) {
    std::vector<std::size_t> clusters{0};
    for (std::size_t j = 0; j < 30; ++j) clusters.push_back(1 + (i * 30 + j) % (n_clusters - 1));
    std::vector<Descriptor> image;
    std::vector<std::size_t> labels;
    for (const std::size_t c : clusters)
      for (int m = 0; m < 2; ++m) {
        image.push_back(member_of(data.centres[c], rng));
        labels.push_back(c);
        data.members[c].push_back(image.back());
      }
    data.images.push_back(std::move(image));
    data.image_clusters.push_back(std::move(labels));
  }
  return data;
}

VocabularyTrainingOptions small_options(std::uint64_t seed = 7) {
  VocabularyTrainingOptions o;
  o.k = 5;
  o.levels = 3;
  o.seed = seed;
  return o;
}

// One vocabulary for the tests that only read it.
class VocabularyTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    data_ = std::make_unique<ClusteredData>(make_clustered_data(42));
    vocabulary_ = std::make_unique<Vocabulary>(Vocabulary::train(data_->images, small_options()));
  }
  static void TearDownTestSuite() {
    vocabulary_.reset();
    data_.reset();
    std::error_code ec;
    fs::remove_all(temp_dir(), ec);
  }
  static const Vocabulary& voc() { return *vocabulary_; }
  static const ClusteredData& data() { return *data_; }

  static fs::path temp_dir() {
    return fs::path(::testing::TempDir()) / ("orbatlas_vocabulary_" + std::to_string(::getpid()));
  }
  static fs::path temp_path(const std::string& name) {
    fs::create_directories(temp_dir());
    return temp_dir() / name;
  }

 private:
  static inline std::unique_ptr<ClusteredData> data_;
  static inline std::unique_ptr<Vocabulary> vocabulary_;
};

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

TEST_F(VocabularyTest, SaveLoadRoundTrip) {
  const fs::path path = temp_path("roundtrip.vocab");
  voc().save(path);
  const Vocabulary loaded = Vocabulary::load(path);
  const VocabularyInfo &a = voc().info(), &b = loaded.info();
  EXPECT_EQ(a.k, b.k);
  EXPECT_EQ(a.levels, b.levels);
  EXPECT_EQ(a.words, b.words);
  EXPECT_EQ(a.nodes, b.nodes);
  EXPECT_EQ(a.weighting, b.weighting);
  EXPECT_EQ(a.scoring, b.scoring);
  EXPECT_EQ(a.descriptor, b.descriptor);
  EXPECT_EQ(a.hash, b.hash);
  EXPECT_EQ(a.training_images, b.training_images);
  EXPECT_EQ(a.training_descriptors, b.training_descriptors);

  std::mt19937_64 rng(5);
  for (int i = 0; i < 1000; ++i) {
    const Descriptor d = random_descriptor(rng);
    ASSERT_EQ(voc().word_of(d), loaded.word_of(d));
  }
  for (WordId w = 0; w < a.words; ++w) ASSERT_EQ(voc().word_weight(w), loaded.word_weight(w));
  for (std::size_t i = 0; i + 1 < data().images.size(); ++i) {
    BowVector p1, q1, p2, q2;
    voc().transform(data().images[i], &p1, nullptr);
    voc().transform(data().images[i + 1], &q1, nullptr);
    loaded.transform(data().images[i], &p2, nullptr);
    loaded.transform(data().images[i + 1], &q2, nullptr);
    EXPECT_EQ(p1, p2);
    EXPECT_EQ(Vocabulary::score(p1, q1), Vocabulary::score(p2, q2));
  }
  // Saving the loaded vocabulary gives the same bytes.
  const fs::path again = temp_path("roundtrip2.vocab");
  loaded.save(again);
  EXPECT_EQ(fs::file_size(path), fs::file_size(again));
  EXPECT_EQ(Vocabulary::load(again).hash(), a.hash);
}

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

// Writes `bytes` to a file and expects load to throw DataError naming it.
void expect_data_error(const fs::path& path, const std::string& bytes, const std::string& what) {
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  }
  try {
    (void)Vocabulary::load(path);
    ADD_FAILURE() << what << ": no error";
  } catch (const DataError& e) {
    EXPECT_NE(std::string(e.what()).find(path.string()), std::string::npos) << e.what();
    std::cout << "  " << what << ": " << e.what() << "\n";
  }
}

TEST_F(VocabularyTest, BadFilesThrowDataError) {
  const fs::path path = temp_path("good.vocab");
  voc().save(path);
  std::string bytes;
  {
    std::ifstream in(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  ASSERT_GT(bytes.size(), 1000u);

  std::string corrupt = bytes;
  corrupt[corrupt.size() / 2] = static_cast<char>(corrupt[corrupt.size() / 2] ^ 0x10);
  expect_data_error(temp_path("corrupt.vocab"), corrupt, "flipped byte");
  expect_data_error(temp_path("half.vocab"), bytes.substr(0, bytes.size() / 2), "truncated to half");
  expect_data_error(temp_path("short.vocab"), bytes.substr(0, bytes.size() - 1), "last byte missing");
  expect_data_error(temp_path("tiny.vocab"), bytes.substr(0, 30), "truncated in the header");
  expect_data_error(temp_path("longer.vocab"), bytes + "x", "trailing byte");
  std::string magic = bytes;
  magic[8] = 'X';
  expect_data_error(temp_path("magic.vocab"), magic, "wrong magic");
  expect_data_error(temp_path("empty.vocab"), "", "empty file");
  expect_data_error(temp_path("text.vocab"), "hello, world\n", "text file");
  std::string version = bytes;
  version[8 + 14] = 9;
  expect_data_error(temp_path("version.vocab"), version, "future version");

  EXPECT_THROW((void)Vocabulary::load(temp_path("does_not_exist.vocab")), DataError);
  EXPECT_THROW((void)Vocabulary::load(temp_path("")), DataError);  // a directory
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

// --- KeyframeDatabase --------------------------------------------------------

TEST_F(VocabularyTest, DatabaseFindsTheSameImageFirst) {
  KeyframeDatabase db;
  std::vector<BowVector> bows(data().images.size());
  for (std::size_t i = 0; i < bows.size(); ++i) {
    voc().transform(data().images[i], &bows[i], nullptr);
    db.add(100 + i, bows[i]);
  }
  EXPECT_EQ(db.size(), bows.size());
  for (std::size_t i = 0; i < bows.size(); i += 7) {
    const auto matches = db.query(bows[i], 5);
    ASSERT_EQ(matches.size(), 5u);
    EXPECT_EQ(matches[0].keyframe, 100 + i);
    EXPECT_NEAR(matches[0].score, 1.0, 1e-12);
    for (std::size_t m = 1; m < matches.size(); ++m) {
      EXPECT_GE(matches[m - 1].score, matches[m].score);
      EXPECT_NEAR(matches[m].score, Vocabulary::score(bows[i], bows[matches[m].keyframe - 100]), 1e-15);
    }
  }
  // All matches, best first, exactly the keyframes sharing a word.
  const auto all = db.query(bows[0], 1000);
  std::size_t sharing = 0;
  for (const BowVector& b : bows) sharing += Vocabulary::score(bows[0], b) > 0 ? 1 : 0;
  EXPECT_EQ(all.size(), sharing);

  // Excluded ids are skipped.
  const auto excluded = db.query(bows[3], 3, {103, 104});
  ASSERT_FALSE(excluded.empty());
  for (const DatabaseMatch& m : excluded) {
    EXPECT_NE(m.keyframe, 103u);
    EXPECT_NE(m.keyframe, 104u);
  }
  EXPECT_LT(excluded[0].score, 1.0);
}

TEST(KeyframeDatabase, EraseAndReplace) {
  const BowVector a{{1, 0.5}, {2, 0.5}}, b{{2, 0.5}, {3, 0.5}}, c{{7, 1.0}};
  KeyframeDatabase db;
  db.add(1, a);
  db.add(2, b);
  db.add(3, a);
  auto m = db.query(a, 10);
  ASSERT_EQ(m.size(), 3u);
  EXPECT_EQ(m[0].keyframe, 1u);  // equal scores: smaller id first
  EXPECT_EQ(m[1].keyframe, 3u);
  EXPECT_EQ(m[2].keyframe, 2u);
  EXPECT_DOUBLE_EQ(m[2].score, 0.5);
  EXPECT_TRUE(db.query(c, 10).empty());  // no shared word

  db.erase(1);
  EXPECT_EQ(db.size(), 2u);
  m = db.query(a, 10);
  ASSERT_EQ(m.size(), 2u);
  EXPECT_EQ(m[0].keyframe, 3u);
  db.erase(1);  // absent: no-op
  db.erase(42);
  EXPECT_EQ(db.size(), 2u);

  db.add(3, c);  // replaces keyframe 3
  EXPECT_EQ(db.size(), 2u);
  m = db.query(a, 10);
  ASSERT_EQ(m.size(), 1u);
  EXPECT_EQ(m[0].keyframe, 2u);
  m = db.query(c, 10);
  ASSERT_EQ(m.size(), 1u);
  EXPECT_EQ(m[0].keyframe, 3u);
  EXPECT_NEAR(m[0].score, 1.0, 1e-15);

  EXPECT_TRUE(db.query(a, 0).empty());
  db.erase(2);
  db.erase(3);
  EXPECT_EQ(db.size(), 0u);
  EXPECT_TRUE(db.query(a, 10).empty());
  EXPECT_TRUE(db.query(c, 10).empty());
}

}  // namespace
}  // namespace orbatlas
