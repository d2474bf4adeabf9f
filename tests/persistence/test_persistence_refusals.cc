// What opening and loading an atlas refuse, and leave untouched: another
// application's database, an atlas of another vocabulary or of a newer schema,
// files that are not an atlas, and corrupt or truncated blobs (DataError).
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <string_view>

#include "core/common/error.h"
#include "core/map/atlas.h"
#include "core/persistence/atlas_store.h"
#include "core/persistence/blob_codec.h"
#include "core/persistence/schema_migrations.h"
#include "core/persistence/sqlite_db.h"
#include "tests/support/persistence_backends.h"
#include "tests/persistence/test_persistence_expect.h"
#include "tests/persistence/test_persistence_random_atlas.h"

namespace orbatlas {
namespace {

namespace fs = std::filesystem;
using namespace test;  // NOLINT: the shared helpers of the persistence tests

constexpr const char* kOtherHash = "00000000deadbeef";

std::string file_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  EXPECT_TRUE(in.good()) << path;
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void write_file(const fs::path& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

template <class F>
std::string data_error_message(F&& f) {
  try {
    f();
  } catch (const DataError& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected DataError, got another exception: " << e.what();
    return {};
  }
  ADD_FAILURE() << "expected DataError, nothing thrown";
  return {};
}

// Instantiated on both backends in test_persistence.cc.
using PersistenceBackends = AtlasBackendTest;

// Opening refuses, before writing anything, another application's database and
// an atlas of another vocabulary (the file-level refusals are SQLite's, below).
TEST_P(PersistenceBackends, OpeningRefusesAnotherApplicationsDatabaseAndAnotherVocabulary) {
  const std::unique_ptr<SqlConnection> raw = raw_connection();
  raw->exec("CREATE TABLE notes (id bigint PRIMARY KEY)");
  std::string message = data_error_message([&] { open_store(test_vocabulary().hash()); });
  EXPECT_NE(message.find("not an orbatlas atlas"), std::string::npos) << message;
  EXPECT_THROW(raw->query_int64("SELECT count(*) FROM atlas"), Error);  // nothing created
  raw->exec("DROP TABLE notes");

  { open_store(test_vocabulary().hash()).save_session(SessionInfo{}); }
  message = data_error_message([&] { open_store(kOtherHash); });
  EXPECT_NE(message.find("vocabulary"), std::string::npos) << message;
  EXPECT_NE(message.find(test_vocabulary().hash()), std::string::npos) << message;
  EXPECT_NE(message.find(kOtherHash), std::string::npos) << message;
  EXPECT_EQ(open_store(test_vocabulary().hash()).load_sessions().size(), 1u);
}

TEST(Persistence, ForeignVocabularyIsRefusedAndTheFileIsUntouched) {
  TempDb db("foreign_vocabulary");
  Atlas atlas;
  build_atlas(atlas, test_vocabulary(), 14);
  {
    AtlasStore store = AtlasStore::open(db.path(), test_vocabulary().hash());
    store.save_atlas(atlas);
  }
  ASSERT_FALSE(fs::exists(db.companion("-wal")));  // checkpointed on close
  const std::string before = file_bytes(db.path());
  const std::string message = data_error_message([&] { AtlasStore::open(db.path(), kOtherHash); });
  EXPECT_NE(message.find("vocabulary"), std::string::npos) << message;
  EXPECT_NE(message.find(test_vocabulary().hash()), std::string::npos) << message;
  EXPECT_EQ(file_bytes(db.path()), before);
  EXPECT_FALSE(fs::exists(db.companion("-wal")));
  // The same for an atlas in rollback-journal mode (e.g. copied with a tool that
  // changed it): the refusal comes before switching to WAL, which would rewrite
  // the header.
  {
    SqliteDb raw(db.path());
    SqliteStatement mode = raw.prepare("PRAGMA journal_mode = DELETE");
    ASSERT_TRUE(mode.step());
    ASSERT_EQ(mode.text(0), "delete");
  }
  const std::string rollback_mode = file_bytes(db.path());
  EXPECT_NE(rollback_mode, before);  // the header records the journal mode
  EXPECT_NE(data_error_message([&] { AtlasStore::open(db.path(), kOtherHash); }).find("vocabulary"), std::string::npos);
  EXPECT_EQ(file_bytes(db.path()), rollback_mode);
  // The right vocabulary still opens it.
  AtlasStore store = AtlasStore::open(db.path(), test_vocabulary().hash());
  Atlas loaded;
  store.load_atlas(loaded, nullptr);
  EXPECT_EQ(count_keyframes(loaded), count_keyframes(atlas));
}

TEST(Persistence, NewerSchemaIsRefusedAndTheFileIsUntouched) {
  TempDb db("newer_schema");
  { AtlasStore::open(db.path(), test_vocabulary().hash()); }
  {
    SqliteDb raw(db.path());
    raw.exec("PRAGMA user_version = " + std::to_string(latest_schema_version() + 1));
  }
  const std::string before = file_bytes(db.path());
  const std::string message = data_error_message([&] { AtlasStore::open(db.path(), test_vocabulary().hash()); });
  EXPECT_NE(message.find("newer"), std::string::npos) << message;
  EXPECT_EQ(file_bytes(db.path()), before);
}

TEST(Persistence, NonAtlasFilesAreRefusedAndUntouched) {
  // A text file.
  TempDb text("not_sqlite");
  std::string junk = "this is not an SQLite database but a plain text file\n";
  for (int i = 0; i < 6; ++i) junk += junk;
  write_file(text.path(), junk);
  const std::string message = data_error_message([&] { AtlasStore::open(text.path(), test_vocabulary().hash()); });
  EXPECT_NE(message.find("not an SQLite database"), std::string::npos) << message;
  EXPECT_NE(message.find(text.path().string()), std::string::npos) << message;
  EXPECT_EQ(file_bytes(text.path()), junk);

  // Another application's SQLite database.
  TempDb foreign("foreign_sqlite");
  {
    SqliteDb raw(foreign.path());
    raw.exec("CREATE TABLE notes(id INTEGER PRIMARY KEY, body TEXT); INSERT INTO notes(body) VALUES ('hello')");
  }
  const std::string before = file_bytes(foreign.path());
  const std::string m2 = data_error_message([&] { AtlasStore::open(foreign.path(), test_vocabulary().hash()); });
  EXPECT_NE(m2.find("not an orbatlas atlas"), std::string::npos) << m2;
  EXPECT_EQ(file_bytes(foreign.path()), before);

  // A folder that does not exist: a plain Error naming the path.
  const fs::path missing = fs::temp_directory_path() / "orbatlas_no_such_folder_for_test" / "atlas.db";
  EXPECT_THROW(AtlasStore::open(missing, test_vocabulary().hash()), Error);
}

TEST(Persistence, CorruptBlobsAreDataErrors) {
  TempDb db("corrupt");
  Atlas atlas;
  build_atlas(atlas, test_vocabulary(), 15);
  const KeyframeId victim = atlas.maps()[0]->keyframes()[2]->id();
  const MapPointId point = atlas.maps()[0]->map_points()[0]->id();
  {
    AtlasStore store = AtlasStore::open(db.path(), test_vocabulary().hash());
    store.save_atlas(atlas);
  }
  const auto tamper_and_load = [&](const std::string& sql) {
    {
      AtlasStore store = AtlasStore::open(db.path(), test_vocabulary().hash());
      store.save_atlas(atlas);  // restore the sound rows first
    }
    {
      SqliteDb raw(db.path());
      raw.exec(sql);
    }
    AtlasStore store = AtlasStore::open(db.path(), test_vocabulary().hash());
    Atlas loaded;
    return data_error_message([&] { store.load_atlas(loaded, &test_vocabulary()); });
  };
  const std::string where = " WHERE id = " + std::to_string(victim);
  std::string m = tamper_and_load("UPDATE keyframes SET features = substr(features, 1, 200)" + where);
  EXPECT_NE(m.find("truncated"), std::string::npos) << m;
  EXPECT_NE(m.find("keyframe " + std::to_string(victim)), std::string::npos) << m;
  m = tamper_and_load("UPDATE keyframes SET features = CAST(X'09000000' || substr(features, 5) AS BLOB)" + where);
  EXPECT_NE(m.find("unknown version 9"), std::string::npos) << m;
  m = tamper_and_load("UPDATE keyframes SET features = CAST(features || X'00' AS BLOB)" + where);
  EXPECT_NE(m.find("trailing"), std::string::npos) << m;
  m = tamper_and_load("UPDATE keyframes SET features = X''" + where);
  EXPECT_NE(m.find("version tag"), std::string::npos) << m;
  m = tamper_and_load("UPDATE keyframes SET slot_count = slot_count + 1" + where);
  EXPECT_NE(m.find("slot_count"), std::string::npos) << m;
  // The schema keeps a descriptor at 32 bytes; with the CHECK bypassed, the codec does.
  m = tamper_and_load("PRAGMA ignore_check_constraints = ON; UPDATE map_points SET descriptor = X'0102' WHERE id = " +
                      std::to_string(point));
  EXPECT_NE(m.find("descriptor"), std::string::npos) << m;

  // Culled keyframes whose chain of parents cannot be resolved.
  std::int64_t culled = 0, chained = 0;
  {
    SqliteDb raw(db.path());
    chained = raw.query_int64("SELECT id FROM culled_keyframes WHERE parent_id IN (SELECT id FROM culled_keyframes)");
    culled = raw.query_int64("SELECT parent_id FROM culled_keyframes WHERE id = " + std::to_string(chained));
  }
  m = tamper_and_load("UPDATE culled_keyframes SET parent_id = 999999 WHERE id = " + std::to_string(culled));
  EXPECT_NE(m.find("parent 999999 is neither"), std::string::npos) << m;
  m = tamper_and_load("UPDATE culled_keyframes SET parent_id = " + std::to_string(chained) +
                      " WHERE id = " + std::to_string(culled));
  EXPECT_NE(m.find("cycle"), std::string::npos) << m;
}

TEST(Persistence, FeaturesBlobRejectsEveryTruncation) {
  std::mt19937_64 rng(31);
  const ImageFeatures features = random_features(rng, 5);
  const std::vector<float> depth = {1, -1, 2, 3, -1}, u_right = {10, -1, 20, 30, -1};
  const std::string blob = encode_features(features, depth, u_right);
  const StoredFeatures decoded = decode_features(blob, "test");
  EXPECT_EQ(decoded.features.descriptors, features.descriptors);
  EXPECT_EQ(decoded.depth, depth);
  EXPECT_EQ(decoded.u_right, u_right);
  for (std::size_t n = 0; n < blob.size(); ++n)
    EXPECT_THROW(decode_features(std::string_view(blob).substr(0, n), "test"), DataError) << n << " bytes";
  // A huge announced keypoint count is refused before anything is allocated.
  std::string huge = blob;
  const std::uint64_t count = 1ULL << 60;
  std::memcpy(huge.data() + 12, &count, sizeof(count));
  EXPECT_THROW(decode_features(huge, "test"), DataError);
  // Monocular, no descriptors, no keypoints: all round-trip.
  const StoredFeatures empty = decode_features(encode_features(ImageFeatures{}, {}, {}), "test");
  EXPECT_TRUE(empty.features.keypoints.empty());
  EXPECT_THROW(encode_features(features, {1.0f}, {1.0f}), Error);  // stereo vectors of the wrong size
  EXPECT_THROW(decode_descriptor("short", "test"), DataError);
  EXPECT_THROW(decode_doubles("1234567", "test"), DataError);
}

}  // namespace
}  // namespace orbatlas
