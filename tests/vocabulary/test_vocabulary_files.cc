// Vocabulary files: a save / load round trip to the same words, weights and
// bytes, and damaged or foreign files refused with a DataError naming them.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>

#include "core/common/error.h"
#include "core/vocabulary/vocabulary.h"
#include "tests/support/vocabulary_data.h"

namespace orbatlas {
namespace {

namespace fs = std::filesystem;
using test::random_descriptor;
using test::VocabularyTest;

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

}  // namespace
}  // namespace orbatlas
