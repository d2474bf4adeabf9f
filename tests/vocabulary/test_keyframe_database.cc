// The KeyframeDatabase (inverted index of keyframes' words): the same image
// found first with the scores of the vocabulary, exclusions, erasing and
// replacing keyframes.
#include <gtest/gtest.h>

#include <vector>

#include "core/vocabulary/keyframe_database.h"
#include "core/vocabulary/vocabulary.h"
#include "tests/support/vocabulary_data.h"

namespace orbatlas {
namespace {

using test::VocabularyTest;

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
