#pragma once
// Random atlas content for the persistence tests (and the crash-safety helper
// program, which has no GTest): features with every field set, keyframes, map
// points, observations, and a two-map atlas with every kind of content. Failures
// throw orbatlas::Error.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "core/map/atlas.h"
#include "core/vocabulary/vocabulary.h"

namespace orbatlas::test {

// A database path in the temp folder, unique per process and name; removed
// (with its WAL companions) at construction and destruction.
class TempDb {
 public:
  explicit TempDb(const std::string& name);
  ~TempDb();
  TempDb(const TempDb&) = delete;
  TempDb& operator=(const TempDb&) = delete;
  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path companion(const char* suffix) const { return std::filesystem::path(path_.string() + suffix); }

 private:
  void remove_all() const;
  std::filesystem::path path_;
};

// A small vocabulary trained on random descriptors, for BoW recomputation.
const Vocabulary& test_vocabulary();

Descriptor random_descriptor(std::mt19937_64& rng);
Pose3 random_pose(std::mt19937_64& rng);
ImageFeatures random_features(std::mt19937_64& rng, std::size_t n, bool descriptors = true);

// A keyframe with n random keypoints (stereo: depth / u_right, a quarter
// unmatched); BoW computed when `vocabulary` is given.
std::shared_ptr<KeyFrame> add_random_keyframe(Map& map, std::mt19937_64& rng, const Vocabulary* vocabulary,
                                              std::size_t n, bool stereo, bool descriptors = true);
// A point with random position, normal, distances, descriptor and statistics.
std::shared_ptr<MapPoint> add_random_point(Map& map, std::mt19937_64& rng);
// Observes each point from min..max random keyframes, at free slots.
void observe_randomly(const std::vector<std::shared_ptr<KeyFrame>>& kfs,
                      const std::vector<std::shared_ptr<MapPoint>>& points, std::mt19937_64& rng,
                      std::size_t min_observers, std::size_t max_observers);

// Two maps with every kind of content, an empty third map, culled keyframes and
// points (the last ids handed out belong to culled objects, and a culled
// keyframe's parent is culled later: a chain of anchors), asymmetric
// covisibility, and an active map that is not the last one created.
void build_atlas(Atlas& atlas, const Vocabulary& vocabulary, std::uint64_t seed);

}  // namespace orbatlas::test
