#pragma once
// ORB-SLAM3's place recognition for keyframes that local mapping has processed
// (docs/loop_closing.md):
//  1. the bag-of-words index gives the best candidates of the same map (loops) or
//     of other maps (merges, PlaceScope), excluding
//     the keyframe's covisibles, grouped by covisibility (top 3 groups);
//  2. a local window: each candidate and its best covisibles, with their points;
//  3. BoW matches keyframe <-> window, Horn 3-point RANSAC scored by
//     reprojection in both keyframes: SE3 when the keyframe's map has metric
//     scale, Sim(3) when its scale is free (a monocular map);
//  4. guided matching: every window point projected with the estimate, the
//     transform refined on the bidirectional reprojection error, then a second,
//     narrower search;
//  5. verification in covisible keyframes of the active map; when fewer than
//     three keyframes agree, later keyframes continue the verification without
//     the bag of words, until three agree or two in a row fail.
// Runs on one thread (the loop closer's); reads the map concurrently.
#include <functional>
#include <memory>
#include <optional>
#include <unordered_set>

#include "core/loop/place_match.h"
#include "core/map/keyframe_index.h"
#include "core/optimization/sim3_refinement.h"
#include "core/estimators/sim3_solver.h"
#include "core/tracking/frame.h"
#include "core/tracking/frame_camera.h"

namespace orbatlas {

// Where the recogniser looks: the keyframe's own map (loop closing) or the
// other maps of the atlas (map merging).
enum class PlaceScope { kSameMap, kOtherMaps };

struct PlaceRecognitionOptions {
  PlaceScope scope = PlaceScope::kSameMap;
  // kOtherMaps: the maps candidates may come from (called under the index's
  // lock: it must not block); empty accepts every other map.
  std::function<bool(MapId)> may_use_map;
  std::size_t candidates = 3;          // covisibility groups tried
  std::size_t index_results = 20;      // BoW results the groups are formed from
  std::size_t window_covisibles = 10;  // ORB-SLAM3's local window
  float bow_ratio = 0.9f;              // SearchByBoW ratio for loops (ORB-SLAM3)
  int min_bow_matches = 20;            // nBoWMatches
  int min_ransac_inliers = 15;         // nBoWInliers
  float first_search_th = 3.0f;        // guided search radius factor (x 2.5-4 px x scale)
  int min_projection_matches = 50;     // nProjMatches
  int min_refined_inliers = 20;        // nSim3Inliers
  float second_search_th = 1.5f;       // the narrower second pass
  int min_final_matches = 80;          // nProjOptMatches
  int verify_matches = 30;             // a covisible / later keyframe confirms with this many
  int verify_keyframes = 3;            // keyframes that must agree
  int max_consecutive_failures = 2;    // later keyframes failing in a row drop the hypothesis
  std::size_t verify_covisibles = 5;   // covisibles of the detecting keyframe tried at once
  std::uint64_t seed = 1;

  // Throws Error naming the first value out of range.
  void check() const;
};

struct PlaceRecognitionStep {
  std::optional<PlaceMatch> match;  // verified this time
  bool bow_candidates = false;      // the index gave candidates
  bool hypothesis = false;          // a geometric hypothesis passed the final search
  bool pending = false;             // waiting for later keyframes
  int best_matches = 0;
};

class PlaceRecognizer {
 public:
  // `index` and the camera must outlive the recogniser.
  PlaceRecognizer(const KeyframeIndex& index, FrameCamera cam, PlaceRecognitionOptions options = {});

  // `free_scale`: the keyframe's map has no metric scale (monocular, no IMU
  // yet), so the transform to the place is a similarity.
  PlaceRecognitionStep process(const std::shared_ptr<KeyFrame>& keyframe, bool free_scale = false);

 private:
  struct Hypothesis {
    PlaceMatch match;
    int failures = 0;
  };

  std::optional<PlaceMatch> detect(const std::shared_ptr<KeyFrame>& keyframe, bool free_scale,
                                   PlaceRecognitionStep& step);
  // `connected`: the keyframe and its covisibles (left out of the window).
  std::optional<PlaceMatch> try_candidate(const std::shared_ptr<KeyFrame>& keyframe,
                                          const std::shared_ptr<KeyFrame>& candidate,
                                          const std::unordered_set<KeyframeId>& connected, bool free_scale);
  // The 3D-3D match of a keyframe slot with a window point, both in camera frames.
  std::optional<Sim3Match> make_match(const KeyFrame& keyframe, const Pose3& T_a_w, std::size_t slot,
                                      const KeyFrame& matched, const Pose3& T_m_w, const MapPoint& point) const;
  // Window points associated with `keyframe` when its camera is at T_c_w (narrow search).
  int confirm(const KeyFrame& keyframe, const Pose3& T_c_w, const PlaceMatch& match) const;
  void verify_with_covisibles(PlaceMatch& match) const;

  const KeyframeIndex& index_;
  const FrameCamera cam_;
  const PlaceRecognitionOptions options_;
  std::optional<Hypothesis> pending_;
  std::uint64_t attempts_ = 0;  // varies the RANSAC seed between attempts, reproducibly
};

}  // namespace orbatlas
