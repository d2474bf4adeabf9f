// Persistent atlas: SQLite schema, Cereal blobs, save / load round trips, and the
// refusals that must leave a file untouched.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <numeric>
#include <random>
#include <string>

#include "core/common/error.h"
#include "core/map/atlas.h"
#include "core/persistence/atlas_store.h"
#include "core/persistence/blob_codec.h"
#include "core/persistence/schema_migrations.h"
#include "core/persistence/sqlite_db.h"

namespace orbatlas {
namespace {

namespace fs = std::filesystem;

constexpr const char* kOtherHash = "00000000deadbeef";

// A database path in the temp folder, unique per process and test; removed
// (with its WAL companions) at the end.
class TempDb {
 public:
  explicit TempDb(const std::string& name)
      : path_(fs::temp_directory_path() /
              ("orbatlas_test_persistence_" + std::to_string(::getpid()) + "_" + name + ".db")) {
    remove_all();
  }
  ~TempDb() { remove_all(); }
  const fs::path& path() const { return path_; }
  fs::path companion(const char* suffix) const { return fs::path(path_.string() + suffix); }

 private:
  void remove_all() const {
    std::error_code ec;
    for (const char* suffix : {"", "-wal", "-shm", "-journal"}) fs::remove(path_.string() + suffix, ec);
  }
  fs::path path_;
};

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

// --- random content ---

Descriptor random_descriptor(std::mt19937_64& rng) { return {rng(), rng(), rng(), rng()}; }

Pose3 random_pose(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  return Pose3(Eigen::Quaterniond(n(rng), n(rng), n(rng), n(rng)), Eigen::Vector3d(n(rng), n(rng), n(rng)) * 5.0);
}

ImageFeatures random_features(std::mt19937_64& rng, std::size_t n, bool descriptors = true) {
  std::uniform_real_distribution<float> u(0.0f, 752.0f), v(0.0f, 480.0f), angle(0.0f, 360.0f), response(0.0f, 200.0f);
  std::normal_distribution<double> gauss(0.0, 1.0);
  ImageFeatures f;
  f.width = 752;
  f.height = 480;
  for (std::size_t i = 0; i < n; ++i) {
    Keypoint kp;
    kp.uv = {u(rng), v(rng)};
    kp.level = static_cast<int>(rng() % 8);
    kp.angle_deg = angle(rng);
    kp.response = response(rng);
    kp.bearing = Eigen::Vector3d(gauss(rng), gauss(rng), 1.0 + std::abs(gauss(rng))).normalized();
    kp.uv_undistorted = {u(rng), v(rng)};
    f.keypoints.push_back(kp);
    if (descriptors) f.descriptors.push_back(random_descriptor(rng));
  }
  return f;
}

std::shared_ptr<KeyFrame> add_keyframe(Map& map, std::mt19937_64& rng, const Vocabulary& vocabulary, std::size_t n,
                                       bool stereo, bool descriptors = true) {
  KeyFrameData data;
  data.timestamp_ns = 1'403'636'579'763'555'584LL + static_cast<std::int64_t>(rng() % 1'000'000'000'000ULL);
  data.T_w_b = random_pose(rng);
  data.T_b_c = random_pose(rng);
  data.features = random_features(rng, n, descriptors);
  if (stereo) {
    std::uniform_real_distribution<float> depth(0.5f, 20.0f), column(0.0f, 752.0f);
    for (std::size_t i = 0; i < n; ++i) {
      const bool matched = rng() % 4 != 0;
      data.depth.push_back(matched ? depth(rng) : -1.0f);
      data.u_right.push_back(matched ? column(rng) : -1.0f);
    }
  }
  if (descriptors) vocabulary.transform(data.features.descriptors, &data.bow, &data.feature_vector);
  data.grid = FeatureGrid(data.features);
  return map.new_keyframe(std::move(data));
}

std::shared_ptr<MapPoint> add_point(Map& map, std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 3.0);
  MapPointData data;
  data.p_w = {n(rng), n(rng), n(rng)};
  data.normal = Eigen::Vector3d(n(rng), n(rng), n(rng)).normalized();
  data.min_distance = 0.5f + static_cast<float>(rng() % 100) / 37.0f;
  data.max_distance = data.min_distance * 8.3f;
  data.descriptor = random_descriptor(rng);
  auto mp = map.new_map_point(data);
  mp->increase_visible(static_cast<int>(rng() % 50));
  mp->increase_found(static_cast<int>(rng() % 20));
  return mp;
}

// Observes each point from `observers` random keyframes at free slots.
void observe(const std::vector<std::shared_ptr<KeyFrame>>& kfs, const std::vector<std::shared_ptr<MapPoint>>& points,
             std::mt19937_64& rng, std::size_t min_observers, std::size_t max_observers) {
  std::vector<std::vector<std::size_t>> free_slots(kfs.size());
  for (std::size_t k = 0; k < kfs.size(); ++k) {
    for (std::size_t s = 0; s < kfs[k]->slot_count(); ++s)
      if (!kfs[k]->map_point(s)) free_slots[k].push_back(s);
    std::shuffle(free_slots[k].begin(), free_slots[k].end(), rng);
  }
  for (const auto& mp : points) {
    std::vector<std::size_t> order(kfs.size());
    std::iota(order.begin(), order.end(), 0);
    std::shuffle(order.begin(), order.end(), rng);
    const std::size_t count = min_observers + rng() % (max_observers - min_observers + 1);
    for (std::size_t i = 0; i < std::min(count, order.size()); ++i) {
      auto& slots = free_slots[order[i]];
      if (slots.empty()) continue;
      ASSERT_TRUE(kfs[order[i]]->add_observation(slots.back(), mp));
      slots.pop_back();
    }
  }
}

// Two maps with every kind of content, an empty third map, culled keyframes and
// points (the last ids handed out belong to culled objects), and an active map
// that is not the last one created.
void build_atlas(Atlas& atlas, const Vocabulary& vocabulary, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  auto a = atlas.create_map();
  auto b = atlas.create_map();
  atlas.create_map();  // stays empty

  // Map a: 10 keyframes, one monocular, one without descriptors.
  std::vector<std::shared_ptr<KeyFrame>> ka;
  for (int i = 0; i < 10; ++i) ka.push_back(add_keyframe(*a, rng, vocabulary, 80, i != 4, i != 7));
  std::vector<std::shared_ptr<MapPoint>> pa;
  for (int i = 0; i < 150; ++i) pa.push_back(add_point(*a, rng));
  observe(ka, pa, rng, 2, 6);
  for (const auto& kf : ka) kf->update_connections(8);
  for (std::size_t i = 1; i < ka.size(); ++i) ka[i]->set_parent(ka[i == 5 ? 2 : i - 1]);
  ka[0]->add_loop_edge(ka[8]);
  ka[1]->add_loop_edge(ka[3]);  // goes with ka[3]
  // A reference keyframe that is not the first observer.
  const auto obs = pa[10]->observations();
  ASSERT_GE(obs.size(), 2u);
  pa[10]->set_reference_keyframe(obs.back().kf.lock());
  // Culling: ka[3] has children to reattach and a loop edge; a point goes too.
  ASSERT_TRUE(a->cull_keyframe(ka[3]->id()));
  ASSERT_TRUE(a->cull_map_point(pa[20]->id()));
  // More observations, then only some keyframes update: covisibility becomes
  // asymmetric, as it is at run time.
  std::vector<std::shared_ptr<KeyFrame>> alive_a;
  for (const auto& kf : ka)
    if (!kf->is_bad()) alive_a.push_back(kf);
  std::vector<std::shared_ptr<MapPoint>> more;
  for (int i = 0; i < 40; ++i) more.push_back(add_point(*a, rng));
  observe(alive_a, more, rng, 2, 4);
  for (std::size_t i = 0; i < alive_a.size(); i += 2) alive_a[i]->update_connections(8);
  // A threshold nobody reaches: alive_a[1] keeps only its best neighbour, the
  // others keep their mirrored links to it.
  alive_a[1]->update_connections(1000);

  // Map b: 5 keyframes; its last keyframe and point are culled.
  std::vector<std::shared_ptr<KeyFrame>> kb;
  for (int i = 0; i < 5; ++i) kb.push_back(add_keyframe(*b, rng, vocabulary, 50, true));
  std::vector<std::shared_ptr<MapPoint>> pb;
  for (int i = 0; i < 60; ++i) pb.push_back(add_point(*b, rng));
  observe(kb, pb, rng, 2, 4);
  for (const auto& kf : kb) kf->update_connections();
  for (std::size_t i = 1; i < kb.size(); ++i) kb[i]->set_parent(kb[0]);
  kb[1]->add_loop_edge(kb[3]);
  auto last_kf = add_keyframe(*b, rng, vocabulary, 20, true);
  auto last_mp = add_point(*b, rng);
  ASSERT_TRUE(b->cull_keyframe(last_kf->id()));
  ASSERT_TRUE(b->cull_map_point(last_mp->id()));

  atlas.set_active(a->id());
}

// --- comparison of every field ---

void expect_pose_eq(const Pose3& a, const Pose3& b, const std::string& what) {
  EXPECT_EQ(a.q.coeffs(), b.q.coeffs()) << what;
  EXPECT_EQ(a.t, b.t) << what;
}

void expect_keyframe_eq(const Map& map_a, const KeyFrame& a, const KeyFrame& b, bool same_bow) {
  const std::string what = "keyframe " + std::to_string(a.id());
  EXPECT_EQ(a.id(), b.id());
  EXPECT_EQ(a.map_id(), b.map_id()) << what;
  EXPECT_FALSE(b.is_bad()) << what;
  EXPECT_EQ(a.timestamp_ns(), b.timestamp_ns()) << what;
  expect_pose_eq(a.T_w_b(), b.T_w_b(), what + " T_w_b");
  expect_pose_eq(a.T_b_c(), b.T_b_c(), what + " T_b_c");
  // Features, every field.
  EXPECT_EQ(a.features().width, b.features().width) << what;
  EXPECT_EQ(a.features().height, b.features().height) << what;
  ASSERT_EQ(a.slot_count(), b.slot_count()) << what;
  for (std::size_t i = 0; i < a.slot_count(); ++i) {
    const Keypoint &ka = a.keypoint(i), &kb = b.keypoint(i);
    EXPECT_EQ(ka.uv, kb.uv) << what << " slot " << i;
    EXPECT_EQ(ka.level, kb.level) << what << " slot " << i;
    EXPECT_EQ(ka.angle_deg, kb.angle_deg) << what << " slot " << i;
    EXPECT_EQ(ka.response, kb.response) << what << " slot " << i;
    EXPECT_EQ(ka.bearing, kb.bearing) << what << " slot " << i;
    EXPECT_EQ(ka.uv_undistorted, kb.uv_undistorted) << what << " slot " << i;
    EXPECT_EQ(a.depth(i), b.depth(i)) << what << " slot " << i;
    EXPECT_EQ(a.u_right(i), b.u_right(i)) << what << " slot " << i;
  }
  EXPECT_EQ(a.features().descriptors, b.features().descriptors) << what;
  EXPECT_EQ(a.is_stereo(), b.is_stereo()) << what;
  if (same_bow) {
    EXPECT_EQ(a.bow(), b.bow()) << what;
    EXPECT_EQ(a.feature_vector(), b.feature_vector()) << what;
  } else {
    EXPECT_TRUE(b.bow().empty()) << what;
    EXPECT_TRUE(b.feature_vector().empty()) << what;
  }
  // The rebuilt grid answers like the original.
  EXPECT_EQ(a.grid().size(), b.grid().size()) << what;
  EXPECT_EQ(a.grid().cols(), b.grid().cols()) << what;
  EXPECT_EQ(a.grid().rows(), b.grid().rows()) << what;
  for (const Eigen::Vector2f& uv : {Eigen::Vector2f(100, 100), Eigen::Vector2f(400, 250), Eigen::Vector2f(700, 450)})
    EXPECT_EQ(a.grid().in_radius(uv, 60.0f), b.grid().in_radius(uv, 60.0f)) << what;
  // Observations and graph.
  const auto sa = a.slots(), sb = b.slots();
  for (std::size_t i = 0; i < sa.size(); ++i) {
    ASSERT_EQ(sa[i] == nullptr, sb[i] == nullptr) << what << " slot " << i;
    if (sa[i]) {
      EXPECT_EQ(sa[i]->id(), sb[i]->id()) << what << " slot " << i;
    }
  }
  EXPECT_EQ(a.map_point_count(), b.map_point_count()) << what;
  EXPECT_EQ(a.redundant_map_point_count(), b.redundant_map_point_count()) << what;
  // Links to culled keyframes are not stored: culling erases only the links the
  // culled keyframe itself holds, so a neighbour whose mirrored link it had
  // dropped keeps a dead one (as in ORB-SLAM); it is not worth persisting.
  std::vector<CovisibilityEdge> ca;
  for (const CovisibilityEdge& edge : a.connections())
    if (map_a.keyframe(edge.keyframe)) ca.push_back(edge);
  const auto cb = b.connections();
  ASSERT_EQ(ca.size(), cb.size()) << what;
  for (std::size_t i = 0; i < ca.size(); ++i) {
    EXPECT_EQ(ca[i].keyframe, cb[i].keyframe) << what << " connection " << i;
    EXPECT_EQ(ca[i].weight, cb[i].weight) << what << " connection " << i;
  }
  EXPECT_EQ(a.parent_id(), b.parent_id()) << what;
  EXPECT_EQ(a.child_ids(), b.child_ids()) << what;
  EXPECT_EQ(a.loop_edge_ids(), b.loop_edge_ids()) << what;
}

void expect_point_eq(const MapPoint& a, const MapPoint& b) {
  const std::string what = "map point " + std::to_string(a.id());
  EXPECT_EQ(a.id(), b.id());
  EXPECT_EQ(a.map_id(), b.map_id()) << what;
  EXPECT_EQ(a.p_w(), b.p_w()) << what;
  EXPECT_EQ(a.normal(), b.normal()) << what;
  EXPECT_EQ(a.min_distance(), b.min_distance()) << what;
  EXPECT_EQ(a.max_distance(), b.max_distance()) << what;
  EXPECT_EQ(a.descriptor(), b.descriptor()) << what;
  EXPECT_EQ(a.reference_keyframe_id(), b.reference_keyframe_id()) << what;
  EXPECT_EQ(a.visible(), b.visible()) << what;
  EXPECT_EQ(a.found(), b.found()) << what;
  const auto oa = a.observations(), ob = b.observations();
  ASSERT_EQ(oa.size(), ob.size()) << what;
  for (std::size_t i = 0; i < oa.size(); ++i) {
    EXPECT_EQ(oa[i].keyframe, ob[i].keyframe) << what;
    EXPECT_EQ(oa[i].slot, ob[i].slot) << what;
    EXPECT_EQ(oa[i].level, ob[i].level) << what;
  }
}

void expect_atlas_eq(const Atlas& a, const Atlas& b, bool same_bow) {
  const auto ma = a.maps(), mb = b.maps();
  ASSERT_EQ(ma.size(), mb.size());
  ASSERT_NE(a.active_map(), nullptr);
  ASSERT_NE(b.active_map(), nullptr);
  EXPECT_EQ(a.active_map()->id(), b.active_map()->id());
  for (std::size_t m = 0; m < ma.size(); ++m) {
    ASSERT_EQ(ma[m]->id(), mb[m]->id());
    const auto ka = ma[m]->keyframes(), kb = mb[m]->keyframes();
    ASSERT_EQ(ka.size(), kb.size()) << "map " << ma[m]->id();
    for (std::size_t i = 0; i < ka.size(); ++i) expect_keyframe_eq(*ma[m], *ka[i], *kb[i], same_bow);
    const auto pa = ma[m]->map_points(), pb = mb[m]->map_points();
    ASSERT_EQ(pa.size(), pb.size()) << "map " << ma[m]->id();
    for (std::size_t i = 0; i < pa.size(); ++i) expect_point_eq(*pa[i], *pb[i]);
  }
  for (const IdKind kind : {IdKind::keyframe, IdKind::map_point, IdKind::map})
    EXPECT_EQ(a.ids().peek(kind), b.ids().peek(kind)) << "id kind " << static_cast<int>(kind);
}

// A small vocabulary trained on random descriptors, for BoW recomputation.
const Vocabulary& test_vocabulary() {
  static const Vocabulary vocabulary = [] {
    std::mt19937_64 rng(3);
    std::vector<std::vector<Descriptor>> images(6);
    for (auto& image : images)
      for (int i = 0; i < 100; ++i) image.push_back(random_descriptor(rng));
    VocabularyTrainingOptions options;
    options.k = 4;
    options.levels = 3;
    options.threads = 1;
    return Vocabulary::train(images, options);
  }();
  return vocabulary;
}

std::size_t count_keyframes(const Atlas& atlas) {
  std::size_t n = 0;
  for (const auto& m : atlas.maps()) n += m->keyframe_count();
  return n;
}

std::size_t count_points(const Atlas& atlas) {
  std::size_t n = 0;
  for (const auto& m : atlas.maps()) n += m->map_point_count();
  return n;
}

// --- tests ---

TEST(Persistence, FreshDatabaseHasTheLatestSchemaInWalMode) {
  TempDb db("fresh");
  TimestampNs created = 0;
  {
    AtlasStore store = AtlasStore::open(db.path(), test_vocabulary().hash());
    EXPECT_EQ(store.schema_version(), latest_schema_version());
    EXPECT_EQ(store.vocabulary_hash(), test_vocabulary().hash());
    EXPECT_GT(store.created_ns(), 0);
    created = store.created_ns();
    EXPECT_TRUE(store.stored_map_ids().empty());
  }
  ASSERT_EQ(schema_migrations().size(), static_cast<std::size_t>(latest_schema_version()));
  EXPECT_EQ(schema_migrations()[0].name, "001_initial.sql");
  SqliteDb raw(db.path());
  EXPECT_EQ(raw.query_int64("PRAGMA user_version"), 1);
  SqliteStatement mode = raw.prepare("PRAGMA journal_mode");
  ASSERT_TRUE(mode.step());
  EXPECT_EQ(mode.text(0), "wal");
  EXPECT_EQ(raw.query_int64("SELECT count(*) FROM schema_migrations WHERE version = 1"), 1);
  // Reopening neither migrates again nor recreates the atlas row.
  AtlasStore again = AtlasStore::open(db.path(), test_vocabulary().hash());
  EXPECT_EQ(again.created_ns(), created);
  EXPECT_EQ(raw.query_int64("SELECT count(*) FROM schema_migrations"), 1);
}

TEST(Persistence, AtlasRoundTripKeepsEveryField) {
  TempDb db("roundtrip");
  const Vocabulary& vocabulary = test_vocabulary();
  Atlas original;
  build_atlas(original, vocabulary, 11);
  ASSERT_GT(original.counters()->keyframes().culled, 0u);
  ASSERT_GT(original.counters()->map_points().culled, 0u);
  // The content is non-trivial where the loader has most to get right.
  int asymmetric = 0, redundant = 0;
  for (const auto& kf : original.maps()[0]->keyframes()) {
    redundant += kf->redundant_map_point_count();
    for (const CovisibilityEdge& edge : kf->connections())
      if (original.maps()[0]->keyframe(edge.keyframe)->weight(kf->id()) != edge.weight) ++asymmetric;
  }
  EXPECT_GT(asymmetric, 0);
  EXPECT_GT(redundant, 0);
  {
    AtlasStore store = AtlasStore::open(db.path(), vocabulary.hash());
    store.save_atlas(original);
  }
  AtlasStore store = AtlasStore::open(db.path(), vocabulary.hash());
  EXPECT_EQ(store.stored_map_ids().size(), 3u);
  Atlas loaded;
  const AtlasLoadReport report = store.load_atlas(loaded, &vocabulary);
  EXPECT_EQ(report.maps, 3u);
  EXPECT_EQ(report.keyframes, count_keyframes(original));
  EXPECT_EQ(report.map_points, count_points(original));
  EXPECT_EQ(report.loop_edges, 2u);  // ka[0]-ka[8] and kb[1]-kb[3]; ka[1]-ka[3] went with ka[3]
  EXPECT_GT(report.covisibility_links, 0u);
  EXPECT_GT(report.observations, 0u);
  expect_atlas_eq(original, loaded, true);

  // Nothing loaded is culled; the counters count what was created by loading.
  EXPECT_EQ(loaded.counters()->keyframes().created, count_keyframes(original));
  EXPECT_EQ(loaded.counters()->keyframes().culled, 0u);
  EXPECT_EQ(loaded.counters()->map_points().created, count_points(original));

  // New ids continue above everything the original atlas handed out, including
  // the culled keyframe and point that had the largest ids.
  const auto map_b = loaded.map(original.maps()[1]->id());
  ASSERT_NE(map_b, nullptr);
  KeyframeId max_loaded_kf = 0;
  for (const auto& m : loaded.maps())
    for (const auto& kf : m->keyframes()) max_loaded_kf = std::max(max_loaded_kf, kf->id());
  const KeyframeId new_kf = map_b->new_keyframe(KeyFrameData{})->id();
  EXPECT_EQ(new_kf, original.ids().peek(IdKind::keyframe));
  EXPECT_GT(new_kf, max_loaded_kf + 1);  // the culled last keyframe's id is skipped
  EXPECT_EQ(map_b->new_map_point({})->id(), original.ids().peek(IdKind::map_point));
  EXPECT_EQ(loaded.create_map()->id(), original.ids().peek(IdKind::map));

  // Loading needs an empty atlas and the store's vocabulary.
  EXPECT_THROW(store.load_atlas(loaded, &vocabulary), Error);
  Atlas other;
  std::mt19937_64 rng(5);
  std::vector<std::vector<Descriptor>> images(2);
  for (auto& image : images)
    for (int i = 0; i < 30; ++i) image.push_back(random_descriptor(rng));
  VocabularyTrainingOptions options;
  options.k = 3;
  options.levels = 2;
  options.threads = 1;
  const Vocabulary foreign = Vocabulary::train(images, options);
  ASSERT_NE(foreign.hash(), vocabulary.hash());
  EXPECT_THROW(store.load_atlas(other, &foreign), Error);
  EXPECT_TRUE(other.maps().empty());
}

TEST(Persistence, LoadingWithoutVocabularyLeavesBowEmpty) {
  TempDb db("nobow");
  Atlas original;
  build_atlas(original, test_vocabulary(), 12);
  AtlasStore store = AtlasStore::open(db.path(), test_vocabulary().hash());
  store.save_atlas(original);
  Atlas loaded;
  store.load_atlas(loaded, nullptr);
  expect_atlas_eq(original, loaded, false);
}

TEST(Persistence, SavingAgainReplacesTheStoredMaps) {
  TempDb db("resave");
  const Vocabulary& vocabulary = test_vocabulary();
  Atlas atlas;
  build_atlas(atlas, vocabulary, 13);
  AtlasStore store = AtlasStore::open(db.path(), vocabulary.hash());
  SessionInfo session;
  session.id = 7;
  session.name = "MH_01";
  store.save_session(session);

  const auto map_a = atlas.maps()[0];
  const auto kfs = map_a->keyframes();
  AtlasSaveOptions options;
  options.keyframe_sessions[kfs[0]->id()] = 7;
  options.keyframe_sessions[kfs[2]->id()] = 7;
  store.save_atlas(atlas, options);

  // Edit: cull a keyframe and a point, move a keyframe, change a point.
  ASSERT_TRUE(map_a->cull_keyframe(kfs[1]->id()));
  const auto points = map_a->map_points();
  ASSERT_TRUE(map_a->cull_map_point(points[5]->id()));
  kfs[4]->set_T_w_b(Pose3(Eigen::Quaterniond(0.5, 0.5, -0.5, 0.5), Eigen::Vector3d(1, 2, 3)));
  points[6]->set_p_w({9, 8, 7});
  points[6]->increase_found(3);
  store.save_atlas(atlas);  // no session options: the stored ones stay
  int dead_links = 0;  // see expect_keyframe_eq
  for (const auto& kf : map_a->keyframes())
    for (const CovisibilityEdge& edge : kf->connections()) dead_links += map_a->keyframe(edge.keyframe) ? 0 : 1;
  EXPECT_GT(dead_links, 0);

  Atlas loaded;
  const AtlasLoadReport report = store.load_atlas(loaded, &vocabulary);
  expect_atlas_eq(atlas, loaded, true);
  EXPECT_EQ(loaded.map(map_a->id())->keyframe(kfs[1]->id()), nullptr);
  EXPECT_EQ(report.keyframe_sessions.size(), 2u);
  EXPECT_EQ(report.keyframe_sessions.at(kfs[0]->id()), 7u);
  EXPECT_EQ(report.keyframe_sessions.at(kfs[2]->id()), 7u);

  // A map stored earlier but no longer in the atlas stays stored.
  Atlas small;
  small.add_map(100);
  store.save_atlas(small);
  std::vector<MapId> ids = store.stored_map_ids();
  EXPECT_EQ(ids.size(), 4u);
  EXPECT_EQ(ids.back(), 100u);
  // A keyframe session naming no stored session is refused, and nothing changes.
  AtlasSaveOptions bad;
  bad.keyframe_sessions[kfs[0]->id()] = 999;
  EXPECT_THROW(store.save_atlas(atlas, bad), Error);
  Atlas reloaded;
  EXPECT_EQ(store.load_atlas(reloaded, nullptr).keyframe_sessions.size(), 2u);
}

CameraCalibration camera(CameraModel model, std::vector<double> distortion, double shift) {
  CameraCalibration c;
  c.model = model;
  c.fx = 458.654 + shift;
  c.fy = 457.296 + shift;
  c.cx = 367.215;
  c.cy = 248.375;
  c.distortion = std::move(distortion);
  c.width = 752;
  c.height = 480;
  c.rate_hz = 20.0;
  c.T_b_c = Pose3(Eigen::Quaterniond(0.7123, -0.0077, 0.0105, 0.7018), Eigen::Vector3d(-0.0216, -0.0647, 0.0098 + shift));
  return c;
}

void expect_session_eq(const SessionInfo& a, const SessionInfo& b) {
  EXPECT_EQ(a.id, b.id);
  EXPECT_EQ(a.name, b.name);
  EXPECT_EQ(a.sensor, b.sensor);
  EXPECT_EQ(a.created_ns, b.created_ns);
  ASSERT_EQ(a.cameras.size(), b.cameras.size());
  for (std::size_t i = 0; i < a.cameras.size(); ++i) {
    const CameraCalibration &ca = a.cameras[i], &cb = b.cameras[i];
    EXPECT_EQ(ca.model, cb.model);
    EXPECT_EQ(ca.fx, cb.fx);
    EXPECT_EQ(ca.fy, cb.fy);
    EXPECT_EQ(ca.cx, cb.cx);
    EXPECT_EQ(ca.cy, cb.cy);
    EXPECT_EQ(ca.distortion, cb.distortion);
    EXPECT_EQ(ca.width, cb.width);
    EXPECT_EQ(ca.height, cb.height);
    EXPECT_EQ(ca.rate_hz, cb.rate_hz);
    expect_pose_eq(ca.T_b_c, cb.T_b_c, "T_b_c");
  }
}

TEST(Persistence, SessionsRoundTrip) {
  TempDb db("sessions");
  AtlasStore store = AtlasStore::open(db.path(), test_vocabulary().hash());
  SessionInfo stereo;
  stereo.id = 3;
  stereo.name = "MH_01_easy stereo";
  stereo.sensor = SensorType::kStereo;
  stereo.created_ns = 1'700'000'000'123'456'789LL;
  stereo.cameras = {camera(CameraModel::kPinholeRadTan, {-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05}, 0),
                    camera(CameraModel::kPinholeRadTan, {-0.28368365, 0.07451284, -0.00010473, -3.5552e-05, 1e-7}, 1)};
  SessionInfo fisheye;
  fisheye.id = 1;
  fisheye.name = "fisheye rig, inertial";
  fisheye.sensor = SensorType::kMonocularInertial;
  fisheye.created_ns = 42;
  fisheye.cameras = {camera(CameraModel::kKannalaBrandt, {0.0034, 0.0007, -0.0020, 0.0002}, 2)};
  SessionInfo bare;  // no camera at all
  bare.id = 9;
  bare.name = "";
  store.save_session(stereo);
  store.save_session(fisheye);
  store.save_session(bare);

  const std::vector<SessionInfo> all = store.load_sessions();
  ASSERT_EQ(all.size(), 3u);
  expect_session_eq(all[0], fisheye);
  expect_session_eq(all[1], stereo);
  expect_session_eq(all[2], bare);
  const auto one = store.load_session(3);
  ASSERT_TRUE(one.has_value());
  expect_session_eq(*one, stereo);
  EXPECT_FALSE(store.load_session(4).has_value());

  // Replacing a session (fewer cameras, new name) keeps its trajectory.
  store.save_trajectory(3, {FrameAnchor{100, 0, 1, Pose3()}});
  stereo.name = "renamed";
  stereo.cameras.pop_back();
  store.save_session(stereo);
  expect_session_eq(*store.load_session(3), stereo);
  EXPECT_EQ(store.load_trajectory(3).size(), 1u);

  // The schema refuses an invalid calibration; the stored session is unchanged.
  SessionInfo invalid = stereo;
  invalid.cameras[0].fx = 0;
  EXPECT_THROW(store.save_session(invalid), Error);
  expect_session_eq(*store.load_session(3), stereo);
}

TEST(Persistence, TrajectoryRoundTrip) {
  TempDb db("trajectory");
  AtlasStore store = AtlasStore::open(db.path(), test_vocabulary().hash());
  SessionInfo session;
  session.id = 2;
  store.save_session(session);
  std::mt19937_64 rng(21);
  std::vector<FrameAnchor> anchors;
  for (int i = 0; i < 300; ++i)
    anchors.push_back({1'403'636'579'763'555'584LL + 50'000'000LL * i, static_cast<MapId>(i / 100),
                       static_cast<KeyframeId>(rng() % 1000), random_pose(rng)});
  std::vector<FrameAnchor> shuffled = anchors;  // stored order does not matter: loaded by time
  std::shuffle(shuffled.begin(), shuffled.end(), rng);
  store.save_trajectory(2, shuffled);
  const auto check = [&](const std::vector<FrameAnchor>& loaded) {
    ASSERT_EQ(loaded.size(), anchors.size());
    for (std::size_t i = 0; i < anchors.size(); ++i) {
      EXPECT_EQ(loaded[i].t_ns, anchors[i].t_ns);
      EXPECT_EQ(loaded[i].map, anchors[i].map);
      EXPECT_EQ(loaded[i].reference, anchors[i].reference);
      expect_pose_eq(loaded[i].T_ref_b, anchors[i].T_ref_b, "anchor " + std::to_string(i));
    }
  };
  check(store.load_trajectory(2));
  EXPECT_TRUE(store.load_trajectory(5).empty());

  // A repeated timestamp is refused and the stored trajectory stays.
  std::vector<FrameAnchor> duplicate = {anchors[0], anchors[0]};
  EXPECT_THROW(store.save_trajectory(2, duplicate), Error);
  check(store.load_trajectory(2));
  // Saving again replaces.
  store.save_trajectory(2, {anchors[7]});
  ASSERT_EQ(store.load_trajectory(2).size(), 1u);
  EXPECT_EQ(store.load_trajectory(2)[0].t_ns, anchors[7].t_ns);
  // Unknown session.
  EXPECT_THROW(store.save_trajectory(6, anchors), Error);
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

TEST(Persistence, SchemaConstraintsHold) {
  TempDb db("constraints");
  { AtlasStore::open(db.path(), test_vocabulary().hash()); }
  SqliteDb raw(db.path());
  raw.exec("PRAGMA foreign_keys = ON");
  raw.exec("INSERT INTO sessions(id, name, sensor, created_ns) VALUES (1, 's', 'stereo', 0)");
  raw.exec("INSERT INTO maps(id, saved_ns) VALUES (1, 0)");
  // Quaternion norm, sensor names, slot ranges, foreign keys, the observation trigger.
  EXPECT_THROW(raw.exec("INSERT INTO trajectory VALUES (1, 5, 0, 0, 2, 0, 0, 0, 0, 0, 0)"), Error);
  raw.exec("INSERT INTO trajectory VALUES (1, 5, 0, 0, 1, 0, 0, 0, 0, 0, 0)");
  EXPECT_THROW(raw.exec("INSERT INTO sessions(id, name, sensor, created_ns) VALUES (2, 's', 'lidar', 0)"), Error);
  EXPECT_THROW(raw.exec("INSERT INTO trajectory VALUES (3, 5, 0, 0, 1, 0, 0, 0, 0, 0, 0)"), Error);  // no session 3
  raw.exec("INSERT INTO keyframes(id, map_id, timestamp_ns, qw, qx, qy, qz, tx, ty, tz, "
           "c_qw, c_qx, c_qy, c_qz, c_tx, c_ty, c_tz, slot_count, features) "
           "VALUES (1, 1, 0, 1, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 4, X'')");
  raw.exec("INSERT INTO map_points(id, map_id, x, y, z, nx, ny, nz, min_distance, max_distance, descriptor, visible, "
           "found) VALUES (1, 1, 0, 0, 0, 0, 0, 1, 1, 2, zeroblob(32), 1, 1)");
  EXPECT_THROW(raw.exec("INSERT INTO observations VALUES (1, 4, 1)"), Error);   // slot out of range
  EXPECT_THROW(raw.exec("INSERT INTO observations VALUES (1, -1, 1)"), Error);  // negative slot
  raw.exec("INSERT INTO observations VALUES (1, 3, 1)");
  EXPECT_THROW(raw.exec("INSERT INTO observations VALUES (1, 2, 1)"), Error);  // point already in slot 3
  EXPECT_THROW(raw.exec("UPDATE keyframes SET features = 'text, not a blob'"), Error);  // STRICT types
  EXPECT_THROW(raw.exec("UPDATE map_points SET descriptor = zeroblob(31)"), Error);
  // Deleting the map cascades to everything in it, and not to the trajectory.
  raw.exec("DELETE FROM maps WHERE id = 1");
  EXPECT_EQ(raw.query_int64("SELECT count(*) FROM keyframes"), 0);
  EXPECT_EQ(raw.query_int64("SELECT count(*) FROM observations"), 0);
  EXPECT_EQ(raw.query_int64("SELECT count(*) FROM trajectory"), 1);
}

}  // namespace
}  // namespace orbatlas
