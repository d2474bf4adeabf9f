#include "tests/persistence/test_persistence_random_atlas.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <numeric>

#include "core/common/error.h"

namespace orbatlas::test {

namespace fs = std::filesystem;

TempDb::TempDb(const std::string& name)
    : path_(fs::temp_directory_path() /
            ("orbatlas_test_persistence_" + std::to_string(::getpid()) + "_" + name + ".db")) {
  remove_all();
}

TempDb::~TempDb() { remove_all(); }

void TempDb::remove_all() const {
  std::error_code ec;
  for (const char* suffix : {"", "-wal", "-shm", "-journal", ".lock"}) fs::remove(path_.string() + suffix, ec);
}

const Vocabulary& test_vocabulary() {
  static const Vocabulary vocabulary = [] {  // immutable once built
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

Descriptor random_descriptor(std::mt19937_64& rng) { return {rng(), rng(), rng(), rng()}; }

Pose3 random_pose(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  return Pose3(Eigen::Quaterniond(n(rng), n(rng), n(rng), n(rng)), Eigen::Vector3d(n(rng), n(rng), n(rng)) * 5.0);
}

ImageFeatures random_features(std::mt19937_64& rng, std::size_t n, bool descriptors) {
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

std::shared_ptr<KeyFrame> add_random_keyframe(Map& map, std::mt19937_64& rng, const Vocabulary* vocabulary,
                                              std::size_t n, bool stereo, bool descriptors) {
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
  if (descriptors && vocabulary) vocabulary->transform(data.features.descriptors, &data.bow, &data.feature_vector);
  data.grid = FeatureGrid(data.features);
  return map.new_keyframe(std::move(data));
}

std::shared_ptr<MapPoint> add_random_point(Map& map, std::mt19937_64& rng) {
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

void observe_randomly(const std::vector<std::shared_ptr<KeyFrame>>& kfs,
                      const std::vector<std::shared_ptr<MapPoint>>& points, std::mt19937_64& rng,
                      std::size_t min_observers, std::size_t max_observers) {
  std::vector<std::vector<std::size_t>> free_slots(kfs.size());
  for (std::size_t k = 0; k < kfs.size(); ++k) {
    for (std::size_t s = 0; s < kfs[k]->slot_count(); ++s)
      if (!kfs[k]->map_point(s)) free_slots[k].push_back(s);
    std::shuffle(free_slots[k].begin(), free_slots[k].end(), rng);
  }
  std::vector<std::size_t> order(kfs.size());
  for (const auto& mp : points) {
    std::iota(order.begin(), order.end(), 0);
    std::shuffle(order.begin(), order.end(), rng);
    const std::size_t count = min_observers + rng() % (max_observers - min_observers + 1);
    for (std::size_t i = 0; i < std::min(count, order.size()); ++i) {
      auto& slots = free_slots[order[i]];
      if (slots.empty()) continue;
      ORBATLAS_CHECK(kfs[order[i]]->add_observation(slots.back(), mp), "observation refused");
      slots.pop_back();
    }
  }
}

void build_atlas(Atlas& atlas, const Vocabulary& vocabulary, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  auto a = atlas.create_map();
  auto b = atlas.create_map();
  atlas.create_map();  // stays empty

  // Map a: 10 keyframes, one monocular, one without descriptors.
  std::vector<std::shared_ptr<KeyFrame>> ka;
  for (int i = 0; i < 10; ++i) ka.push_back(add_random_keyframe(*a, rng, &vocabulary, 80, i != 4, i != 7));
  std::vector<std::shared_ptr<MapPoint>> pa;
  for (int i = 0; i < 150; ++i) pa.push_back(add_random_point(*a, rng));
  observe_randomly(ka, pa, rng, 2, 6);
  for (const auto& kf : ka) kf->update_connections(8);
  for (std::size_t i = 1; i < ka.size(); ++i) ka[i]->set_parent(ka[i == 5 ? 2 : i - 1]);
  ka[0]->add_loop_edge(ka[8]);
  ka[1]->add_loop_edge(ka[3]);  // goes with ka[3]
  // A reference keyframe that is not the first observer.
  const auto obs = pa[10]->observations();
  ORBATLAS_CHECK(obs.size() >= 2, "map point 10 has " << obs.size() << " observers");
  pa[10]->set_reference_keyframe(obs.back().kf.lock());
  // Culling: ka[3] has children to reattach and a loop edge; a point goes too.
  // ka[7] (parent ka[6]) and then its parent: a chain of two culled anchors.
  // Keyframes of different units (a monocular map after Sim(3) corrections).
  ka[6]->scale_units(1.5);
  ka[7]->scale_units(0.8);
  ORBATLAS_CHECK(a->cull_keyframe(ka[3]->id()), "cull");
  ORBATLAS_CHECK(a->cull_map_point(pa[20]->id()), "cull");
  ORBATLAS_CHECK(a->cull_keyframe(ka[7]->id()), "cull");
  ORBATLAS_CHECK(a->cull_keyframe(ka[6]->id()), "cull");
  // More observations, then only some keyframes update: covisibility becomes
  // asymmetric, as it is at run time.
  std::vector<std::shared_ptr<KeyFrame>> alive_a;
  for (const auto& kf : ka)
    if (!kf->is_bad()) alive_a.push_back(kf);
  std::vector<std::shared_ptr<MapPoint>> more;
  for (int i = 0; i < 40; ++i) more.push_back(add_random_point(*a, rng));
  observe_randomly(alive_a, more, rng, 2, 4);
  for (std::size_t i = 0; i < alive_a.size(); i += 2) alive_a[i]->update_connections(8);
  // A threshold nobody reaches: alive_a[1] keeps only its best neighbour, the
  // others keep their mirrored links to it.
  alive_a[1]->update_connections(1000);
  // Moving the parent afterwards moves the culled keyframes anchored to it.
  alive_a[2]->set_T_w_b(random_pose(rng));
  alive_a[2]->scale_units(2.0);

  // Map b: 5 keyframes; its last keyframe and point are culled.
  std::vector<std::shared_ptr<KeyFrame>> kb;
  for (int i = 0; i < 5; ++i) kb.push_back(add_random_keyframe(*b, rng, &vocabulary, 50, true));
  std::vector<std::shared_ptr<MapPoint>> pb;
  for (int i = 0; i < 60; ++i) pb.push_back(add_random_point(*b, rng));
  observe_randomly(kb, pb, rng, 2, 4);
  for (const auto& kf : kb) kf->update_connections();
  for (std::size_t i = 1; i < kb.size(); ++i) kb[i]->set_parent(kb[0]);
  kb[1]->add_loop_edge(kb[3]);
  auto last_kf = add_random_keyframe(*b, rng, &vocabulary, 20, true);  // a root: anchored in the world
  auto last_mp = add_random_point(*b, rng);
  kb[2]->scale_units(0.7);
  last_kf->scale_units(1.3);
  ORBATLAS_CHECK(b->cull_keyframe(last_kf->id()), "cull");
  ORBATLAS_CHECK(b->cull_map_point(last_mp->id()), "cull");

  atlas.set_active(a->id());
}

}  // namespace orbatlas::test
