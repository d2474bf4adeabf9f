// orbatlas bench atlas-store: size of the atlas database and the time of a full
// save, a full load (with and without recomputing the bags of words) and of
// incremental checkpoints, on a synthetic atlas shaped like a stereo EuRoC run:
// N keyframes of 1200 ORB keypoints (descriptors, stereo depth), 60 new map
// points per keyframe each seen by ~5 consecutive keyframes, covisibility and a
// spanning tree. `--database postgresql://...` runs it on an empty PostgreSQL
// database instead of a temporary SQLite file. `--from-atlas DB`
// takes a stored atlas (e.g. a full `orbatlas run --atlas`) instead of the
// synthetic one: its load from DB, then the same save, loads and checkpoints
// (without the 10 new keyframes) in the database measured.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <random>
#include <tuple>
#include <unistd.h>

#include "client/benchmarks.h"
#include "core/common/error.h"
#include "core/common/process_memory.h"
#include "core/common/progress.h"
#include "core/map/atlas.h"
#include "core/persistence/atlas_checkpointer.h"
#include "core/persistence/atlas_location.h"
#include "core/persistence/atlas_store.h"
#include "core/persistence/pg_db.h"
#include "core/persistence/sqlite_db.h"
#include "core/vocabulary/default_vocabulary.h"
#include "core/vocabulary/vocabulary.h"

namespace orbatlas::cli {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// Builds the synthetic atlas, and later the keyframes tracking adds to it.
class SyntheticAtlas {
 public:
  SyntheticAtlas(Atlas& atlas, const AtlasStoreBenchOptions& o) : map_(atlas.create_map()), o_(o), rng_(42) {}

  // A keyframe 10 cm further along a straight path, with its keypoints.
  void add_keyframe() {
    KeyFrameData data;
    const auto i = static_cast<std::int64_t>(keyframes_.size());
    data.timestamp_ns = 1'403'636'579'763'555'584LL + i * 250'000'000LL;
    data.T_w_b = Pose3(Eigen::Quaterniond(1, 0, 0, 0), Eigen::Vector3d(0.1 * static_cast<double>(i), 0, 0));
    data.T_b_c = Pose3(Eigen::Quaterniond(0.7123, -0.0077, 0.0105, 0.7018), Eigen::Vector3d(-0.0216, -0.0647, 0.0098));
    std::uniform_real_distribution<float> u(0.0f, 752.0f), v(0.0f, 480.0f), angle(0.0f, 360.0f), depth(0.5f, 15.0f);
    std::geometric_distribution<int> level(0.3);  // most keypoints on the finest levels, as ORB's pyramid
    data.features.width = 752;
    data.features.height = 480;
    for (int k = 0; k < o_.keypoints; ++k) {
      Keypoint kp;
      kp.uv = {u(rng_), v(rng_)};
      kp.level = std::min(level(rng_), 7);
      kp.angle_deg = angle(rng_);
      kp.response = static_cast<float>(rng_() % 200);
      kp.uv_undistorted = kp.uv + Eigen::Vector2f(0.5f, -0.25f);
      kp.bearing = Eigen::Vector3d((kp.uv_undistorted.x() - 367.2) / 458.7, (kp.uv_undistorted.y() - 248.4) / 457.3, 1)
                       .normalized();
      data.features.keypoints.push_back(kp);
      data.features.descriptors.push_back({rng_(), rng_(), rng_(), rng_()});
      const bool matched = rng_() % 10 < 7;  // ~70% of keypoints get a stereo match
      data.depth.push_back(matched ? depth(rng_) : -1.0f);
      data.u_right.push_back(matched ? kp.uv.x() - 40.0f : -1.0f);
    }
    data.grid = FeatureGrid(data.features);
    auto kf = map_->new_keyframe(std::move(data));
    if (!keyframes_.empty()) kf->set_parent(keyframes_.back());
    keyframes_.push_back(kf);
    next_free_slot_.push_back(0);
  }

  // points_per_keyframe new points made at keyframe i, each seen by keyframes i .. i + 4.
  void add_points_of(std::size_t i) {
    std::normal_distribution<double> n(0.0, 2.0);
    for (int p = 0; p < o_.points_per_keyframe; ++p) {
      MapPointData data;
      data.p_w = keyframes_[i]->T_w_b().t + Eigen::Vector3d(n(rng_), n(rng_), 4.0 + std::abs(n(rng_)));
      data.normal = Eigen::Vector3d(0, 0, 1);
      data.min_distance = 1.0f;
      data.max_distance = 8.0f;
      data.descriptor = {rng_(), rng_(), rng_(), rng_()};
      auto mp = map_->new_map_point(data);
      mp->increase_visible(static_cast<int>(rng_() % 30));
      mp->increase_found(static_cast<int>(rng_() % 10));
      for (std::size_t j = i; j < std::min(keyframes_.size(), i + kObservers); ++j) {
        std::size_t& slot = next_free_slot_[j];
        if (slot < keyframes_[j]->slot_count()) keyframes_[j]->add_observation(slot++, mp);
      }
    }
  }

  std::size_t size() const { return keyframes_.size(); }
  const std::shared_ptr<KeyFrame>& keyframe(std::size_t i) const { return keyframes_[i]; }

  static constexpr std::size_t kObservers = 5;

 private:
  std::shared_ptr<Map> map_;
  const AtlasStoreBenchOptions& o_;
  std::mt19937_64 rng_;
  std::vector<std::shared_ptr<KeyFrame>> keyframes_;
  std::vector<std::size_t> next_free_slot_;
};

std::uintmax_t file_size_or_zero(const fs::path& path) {
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  return ec ? 0 : size;
}

void remove_database(const fs::path& path) {
  if (is_postgres_location(path.string())) return;  // left as it is (checked empty at start)
  std::error_code ec;
  for (const char* suffix : {"", "-wal", "-shm"}) fs::remove(path.string() + suffix, ec);
}

// A plain connection to the database (no atlas checks), for its size.
std::unique_ptr<SqlConnection> raw_connection(const fs::path& db) {
  if (is_postgres_location(db.string())) {
    check_postgres_uri(db.string());
    return std::make_unique<PgDb>(db.string());
  }
  return std::make_unique<SqliteDb>(db);
}

// The bench measures a save into an empty database: a PostgreSQL one must be
// empty (it is never cleared), an SQLite file is replaced.
void check_postgres_database_empty(const fs::path& db) {
  if (!is_postgres_location(db.string())) return;
  const std::unique_ptr<SqlConnection> raw = raw_connection(db);
  const std::int64_t tables =
      raw->query_int64("SELECT count(*) FROM information_schema.tables WHERE table_schema = current_schema()");
  ORBATLAS_CHECK(tables == 0,
                 "bench atlas-store: " << raw->description() << " holds " << tables
                                       << " tables; give an empty PostgreSQL database (it is not cleared)");
}

// Bytes the database takes: the SQLite file and its WAL, or PostgreSQL's pg_database_size.
double database_mb(const fs::path& db) {
  if (is_postgres_location(db.string()))
    return static_cast<double>(raw_connection(db)->query_int64("SELECT pg_database_size(current_database())")) / 1e6;
  return static_cast<double>(file_size_or_zero(db) + file_size_or_zero(db.string() + "-wal")) / 1e6;
}

}  // namespace

void run_atlas_store_bench(const AtlasStoreBenchOptions& o) {
  o.check();
  const fs::path db = o.database.empty() ? fs::temp_directory_path() /
                                               ("orbatlas_bench_atlas_store_" + std::to_string(::getpid()) + ".db")
                                         : o.database;
  check_postgres_database_empty(db);
  remove_database(db);

  // The vocabulary, when there is one: its hash names the atlas, and loading
  // recomputes every keyframe's bag of words with it.
  const fs::path vocab_path = o.vocabulary.empty() ? default_vocabulary_path() : o.vocabulary;
  std::optional<Vocabulary> vocabulary;
  if (fs::exists(vocab_path)) vocabulary.emplace(Vocabulary::load(vocab_path));
  const std::string hash = vocabulary ? vocabulary->hash() : "bench-without-vocabulary";

  // 1. The synthetic atlas, or the stored one.
  auto t0 = Clock::now();
  auto atlas = std::make_unique<Atlas>();
  std::optional<SyntheticAtlas> synthetic;
  const bool stored = !o.from_atlas.empty();
  if (stored) {
    ORBATLAS_CHECK(o.from_atlas != db.string(), "bench atlas-store: --from-atlas and --database are the same");
    AtlasStore source = AtlasStore::open(o.from_atlas, hash);
    source.load_atlas(*atlas, nullptr);
  } else {
    synthetic.emplace(*atlas, o);
    Progress progress("building the synthetic atlas", 2 * static_cast<std::int64_t>(o.keyframes));
    for (int i = 0; i < o.keyframes; ++i) {
      synthetic->add_keyframe();
      progress.advance();
    }
    for (std::size_t i = 0; i < synthetic->size(); ++i) {
      synthetic->add_points_of(i);
      progress.advance();
    }
    for (std::size_t i = 0; i < synthetic->size(); ++i) synthetic->keyframe(i)->update_connections();
    progress.finish();
  }
  const double build_s = seconds_since(t0);  // or the stored atlas's load, without BoW
  std::size_t keyframes = 0, points = 0, observations = 0, links = 0;
  for (const auto& map : atlas->maps()) {
    points += map->map_point_count();
    for (const auto& kf : map->keyframes()) {
      ++keyframes;
      observations += static_cast<std::size_t>(kf->map_point_count());
      links += kf->connections().size();
    }
  }

  // 2. Full save, size.
  t0 = Clock::now();
  {
    AtlasStore store = AtlasStore::open(db, hash);
    store.save_atlas(*atlas);
  }
  const double save_s = seconds_since(t0);
  const double size_mb = database_mb(db);
  const double blob_mb =
      static_cast<double>(raw_connection(db)->query_int64("SELECT coalesce(sum(length(features)), 0) FROM keyframes")) /
      1e6;

  // 3. Full loads (the saved atlas is released first, then rebuilt for the checkpoints).
  const auto load_once = [&](const Vocabulary* with) {
    const auto t = Clock::now();
    AtlasStore store = AtlasStore::open(db, hash);
    Atlas loaded;
    store.load_atlas(loaded, with);
    return seconds_since(t);
  };
  const double load_s = load_once(nullptr);
  const double load_bow_s = vocabulary ? load_once(&*vocabulary) : 0.0;

  // 4. Checkpoints: the first rewrites everything, an unchanged atlas writes
  // nothing, then tracking adds 10 keyframes; local mapping makes points
  // between them and the last keyframes before them (so covisibility and
  // observations also change in older keyframes).
  CheckpointOptions manual;
  manual.every_keyframes = 0;
  manual.every_seconds = 0;
  AtlasCheckpointer checkpointer(*atlas, db, hash, manual);
  const auto checkpoint = [&]() {
    ORBATLAS_CHECK(checkpointer.checkpoint_now(), "checkpoint failed: " << checkpointer.stats().last_error);
    const CheckpointStats s = checkpointer.stats();
    return std::make_pair(s.last_ms, s.last_rows);
  };
  const auto [first_ms, first_rows] = checkpoint();
  const auto [unchanged_ms, unchanged_rows] = checkpoint();
  double new_ms = 0.0;
  RowCounts new_rows;
  if (synthetic) {
    const std::size_t before = synthetic->size();
    for (int i = 0; i < 10; ++i) synthetic->add_keyframe();
    for (std::size_t i = before - SyntheticAtlas::kObservers + 1; i < synthetic->size(); ++i)
      synthetic->add_points_of(i);
    for (std::size_t i = before; i < synthetic->size(); ++i) synthetic->keyframe(i)->update_connections();
    std::tie(new_ms, new_rows) = checkpoint();
  }
  checkpointer.stop();
  const double peak_mb = peak_rss_mb();
  if (o.database.empty()) remove_database(db);

  const double per_1000 = size_mb * 1000.0 / static_cast<double>(std::max<std::size_t>(keyframes, 1));
  const auto rows_json = [](const RowCounts& r) {
    return nlohmann::json{{"inserted", r.inserted}, {"updated", r.updated}, {"deleted", r.deleted}};
  };
  if (o.json) {
    nlohmann::json j = {
        {"benchmark", "atlas-store"},
        {"backend", is_postgres_location(db.string()) ? "postgresql" : "sqlite"},
        {"from_atlas", stored ? nlohmann::json(location_for_messages(o.from_atlas)) : nlohmann::json(nullptr)},
        {"keyframes", keyframes},
        {"keypoints_per_keyframe", stored ? nlohmann::json(nullptr) : nlohmann::json(o.keypoints)},
        {"map_points", points},
        {"observations", observations},
        {"covisibility_links", links},
        {stored ? "source_load_s" : "build_s", build_s},
        {"database_mb", size_mb},
        {"database_mb_per_1000_keyframes", per_1000},
        {"features_blobs_mb", blob_mb},
        {"save_s", save_s},
        {"load_s", load_s},
        {"load_with_bow_s", vocabulary ? nlohmann::json(load_bow_s) : nlohmann::json(nullptr)},
        {"vocabulary", vocabulary ? vocab_path.string() : std::string()},
        {"first_checkpoint_ms", first_ms},
        {"first_checkpoint_rows", rows_json(first_rows)},
        {"unchanged_checkpoint_ms", unchanged_ms},
        {"unchanged_checkpoint_rows", rows_json(unchanged_rows)},
        {"checkpoint_10_keyframes_ms", synthetic ? nlohmann::json(new_ms) : nlohmann::json(nullptr)},
        {"checkpoint_10_keyframes_rows", synthetic ? rows_json(new_rows) : nlohmann::json(nullptr)},
        {"peak_rss_mb", peak_mb}};
    std::printf("%s\n", j.dump(2).c_str());
    return;
  }
  const auto rows_text = [](const RowCounts& r) {
    return std::to_string(r.inserted) + " inserted, " + std::to_string(r.updated) + " updated, " +
           std::to_string(r.deleted) + " deleted";
  };
  const double per_keyframe = static_cast<double>(links) / static_cast<double>(std::max<std::size_t>(keyframes, 1));
  const double per_point = static_cast<double>(observations) / static_cast<double>(std::max<std::size_t>(points, 1));
  if (stored) {
    std::printf(
        "atlas store benchmark: the atlas %s, %zu keyframes, %zu map points,\n"
        "  %.1f observations per point, %.1f covisibility links per keyframe (database %s)\n",
        location_for_messages(o.from_atlas).c_str(), keyframes, points, per_point, per_keyframe,
        location_for_messages(db.string()).c_str());
    std::printf("  %-38s %10.2f s\n", "load from it, without BoW", build_s);
  } else {
    std::printf(
        "atlas store benchmark: %zu keyframes x %d keypoints (stereo, descriptors), %zu map points,\n"
        "  %.1f observations per point, %.1f covisibility links per keyframe (database %s)\n",
        keyframes, o.keypoints, points, per_point, per_keyframe, location_for_messages(db.string()).c_str());
    std::printf("  %-38s %10.2f s\n", "build in memory", build_s);
  }
  std::printf("  %-38s %10.1f MB   (%.1f MB per 1000 keyframes; features blobs %.1f MB)\n", "database size", size_mb,
              per_1000, blob_mb);
  std::printf("  %-38s %10.2f s\n", "full save (one transaction)", save_s);
  std::printf("  %-38s %10.2f s\n", "full load, without BoW", load_s);
  if (vocabulary) {
    std::printf("  %-38s %10.2f s    (%s)\n", "full load, BoW recomputed", load_bow_s, vocab_path.c_str());
  } else {
    std::printf("  %-38s %10s      (no vocabulary at %s)\n", "full load, BoW recomputed", "n/a", vocab_path.c_str());
  }
  std::printf("  %-38s %10.1f ms   (%s)\n", "first checkpoint (full rewrite)", first_ms, rows_text(first_rows).c_str());
  std::printf("  %-38s %10.1f ms   (%s)\n", "checkpoint, nothing changed", unchanged_ms,
              rows_text(unchanged_rows).c_str());
  if (synthetic)
    std::printf("  %-38s %10.1f ms   (%s)\n", "checkpoint, 10 new keyframes", new_ms, rows_text(new_rows).c_str());
  std::printf("  %-38s %10.0f MB\n", "peak RSS", peak_mb);
}

}  // namespace orbatlas::cli
