// orbatlas bench place: place recognition and relocalisation recall of one
// recording's frames against the map of another (both with ground truth in one
// world frame, e.g. two Machine Hall sequences). The map is built by stereo SLAM
// over --map; every --every-th frame of --queries that revisits a mapped place
// (its camera within --revisit-m (0.75 m) and --revisit-deg (20 deg) of a
// keyframe's, by the ground truth) is a query. Place recognition: a keyframe
// within twice that distance and 15 deg more among the bag-of-words top 3. Relocalisation: the relocaliser's pose
// within 10 cm and 2 deg of the ground truth in the map's frame (a pose farther off is a false relocalisation). No
// query image built the map.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "client/benchmarks.h"
#include "core/common/data_paths.h"
#include "core/common/error.h"
#include "core/common/progress.h"
#include "core/geometry/trajectory.h"
#include "core/io/euroc_reader.h"
#include "core/io/settings.h"
#include "core/io/tum_trajectory.h"
#include "core/relocalization/relocalizer.h"
#include "core/slam/slam_system.h"
#include "core/tracking/stereo_frontend.h"
#include "core/vocabulary/default_vocabulary.h"

namespace orbatlas::cli {
namespace {

double axis_angle_deg(const Pose3& a, const Pose3& b) {
  const double c = a.rotation().col(2).dot(b.rotation().col(2));
  return std::acos(std::clamp(c, -1.0, 1.0)) * 180.0 / M_PI;
}

Trajectory ground_truth_of(const EurocDataset& ds, const std::filesystem::path& dir) {
  ORBATLAS_CHECK(!ds.ground_truth.empty(), dir.string() << " has no ground truth (mav0/state_groundtruth_estimate0)");
  return from_ground_truth_states(ds.ground_truth);
}

struct MappedKeyframe {
  std::shared_ptr<KeyFrame> keyframe;
  Pose3 T_gt_c;  // ground-truth camera pose (world of the ground truth)
};

}  // namespace

void run_place_bench(const PlaceBenchOptions& o) {
  o.check();
  const auto config = o.config.empty() ? shipped_config_dir() / "euroc" / "stereo.yaml" : o.config;
  const SlamSettings settings = read_settings(config, SensorType::kStereo);
  const Vocabulary vocabulary = Vocabulary::load(o.vocabulary.empty() ? default_vocabulary_path() : o.vocabulary);
  EurocReadOptions ro;
  ro.require_cam1 = true;
  const EurocDataset map_ds = read_euroc_dataset(o.map, ro), query_ds = read_euroc_dataset(o.queries, ro);
  const Trajectory map_gt = ground_truth_of(map_ds, o.map), query_gt = ground_truth_of(query_ds, o.queries);

  // The map: stereo SLAM over the whole --map recording (synchronous mapping).
  Atlas atlas;
  SlamSystemOptions so;
  so.synchronous_mapping = true;
  SlamSystem slam(atlas, settings, vocabulary, so);
  const auto map_frames = pair_stereo_frames(map_ds);
  Progress progress("bench place: mapping", static_cast<std::int64_t>(map_frames.size()), o.show_progress);
  for (const auto& f : map_frames) {
    slam.process(f.t_ns, read_gray(f.left), read_gray(f.right));
    progress.advance();
  }
  progress.finish();
  slam.finish();
  const Pose3 T_b_c = slam.frontend().calibration().T_b_c;

  // Each map's frame in the ground truth's world, from its oldest keyframe.
  std::vector<MappedKeyframe> keyframes;
  std::map<MapId, Pose3> T_gt_map;
  for (const auto& map : atlas.maps()) {
    for (const auto& kf : map->keyframes()) {
      const auto gt = pose_at(map_gt, kf->timestamp_ns(), 50'000'000);
      if (!gt) continue;
      if (!T_gt_map.contains(map->id())) T_gt_map[map->id()] = *gt * kf->T_w_b().inverse();
      keyframes.push_back({kf, *gt * T_b_c});
    }
  }
  ORBATLAS_CHECK(!keyframes.empty(), "the map recording gave no keyframe with ground truth");

  StereoFrontend frontend(settings);
  const FrameCamera cam = frontend.frame_camera();
  const auto query_frames = pair_stereo_frames(query_ds);
  std::size_t queries = 0, recognised = 0, relocalised = 0, false_relocalisations = 0, frames_seen = 0;
  std::vector<double> errors_m, errors_deg;
  Progress qp("bench place: queries", static_cast<std::int64_t>(query_frames.size()), o.show_progress);
  for (std::size_t i = 0; i < query_frames.size(); i += static_cast<std::size_t>(std::max(1, o.every))) {
    const auto& f = query_frames[i];
    qp.advance(std::max(1, o.every));
    const auto gt = pose_at(query_gt, f.t_ns, 50'000'000);
    if (!gt) continue;
    ++frames_seen;
    const Pose3 T_gt_c = *gt * T_b_c;
    const bool revisit = std::any_of(keyframes.begin(), keyframes.end(), [&](const MappedKeyframe& k) {
      return (k.T_gt_c.t - T_gt_c.t).norm() < o.revisit_m && axis_angle_deg(k.T_gt_c, T_gt_c) < o.revisit_deg;
    });
    if (!revisit) continue;
    ++queries;
    Frame frame = frontend.make_frame(f.t_ns, read_gray(f.left), read_gray(f.right));
    vocabulary.transform(frame.features.descriptors, &frame.bow, &frame.feature_vector);
    const auto top = atlas.keyframe_index().query(frame.bow, 3);
    const bool hit = std::any_of(top.begin(), top.end(), [&](const IndexCandidate& c) {
      const auto k = std::find_if(keyframes.begin(), keyframes.end(),
                                  [&](const MappedKeyframe& m) { return m.keyframe == c.keyframe; });
      return k != keyframes.end() && (k->T_gt_c.t - T_gt_c.t).norm() < 2.0 * o.revisit_m &&
             axis_angle_deg(k->T_gt_c, T_gt_c) < o.revisit_deg + 15.0;
    });
    recognised += hit ? 1 : 0;
    const RelocalizationResult r = relocalize(frame, vocabulary, atlas.keyframe_index(), cam, T_b_c);
    if (!r.success) continue;
    const Pose3 estimate = T_gt_map.at(r.map) * r.T_w_b;
    const double e_m = (estimate.t - gt->t).norm(), e_deg = rotation_distance(estimate, *gt) * 180.0 / M_PI;
    if (e_m < 0.10 && e_deg < 2.0) {
      ++relocalised;
      errors_m.push_back(e_m);
      errors_deg.push_back(e_deg);
    } else {
      ++false_relocalisations;
    }
  }
  qp.finish();

  const double n = static_cast<double>(std::max<std::size_t>(1, queries));
  nlohmann::json j = {{"benchmark", "place"},
                      {"map", o.map.string()},
                      {"queries_dataset", o.queries.string()},
                      {"map_keyframes", keyframes.size()},
                      {"query_frames", frames_seen},
                      {"revisit_queries", queries},
                      {"revisit_m", o.revisit_m},
                      {"revisit_deg", o.revisit_deg},
                      {"place_recall_top3", static_cast<double>(recognised) / n},
                      {"relocalisation_recall", static_cast<double>(relocalised) / n},
                      {"false_relocalisations", false_relocalisations},
                      {"relocalisation_error_m_p50", errors_m.empty() ? 0.0 : percentile(errors_m, 0.5)},
                      {"relocalisation_error_deg_p50", errors_deg.empty() ? 0.0 : percentile(errors_deg, 0.5)}};
  if (o.json) {
    std::printf("%s\n", j.dump(2).c_str());
    return;
  }
  std::printf("place benchmark: map %s (%zu keyframes), queries %s\n", o.map.c_str(), keyframes.size(),
              o.queries.c_str());
  std::printf(
      "  %zu query frames, %zu revisit a mapped place (within %.2f m / %.0f deg of a keyframe; none of them "
      "built the map)\n",
      frames_seen, queries, o.revisit_m, o.revisit_deg);
  std::printf("  place recognition: true place in the top 3 for %zu (%.1f%%)\n", recognised, 100.0 * recognised / n);
  std::printf("  relocalisation: %zu within 10 cm / 2 deg (%.1f%%), %zu false; error p50 %.3f m / %.2f deg\n",
              relocalised, 100.0 * relocalised / n, false_relocalisations,
              j["relocalisation_error_m_p50"].get<double>(), j["relocalisation_error_deg_p50"].get<double>());
}

}  // namespace orbatlas::cli
