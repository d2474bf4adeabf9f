// orbatlas bench: benchmarks that print figures (never pass/fail).
#include <memory>

#include "client/benchmarks.h"
#include "client/commands.h"

namespace orbatlas::cli {

void register_bench_command(CLI::App& app) {
  auto* bench = app.add_subcommand("bench", "Benchmarks that print figures");
  bench->require_subcommand(1);

  auto render = std::make_shared<RenderBenchOptions>();
  auto* r = bench->add_subcommand("render", "Milliseconds per rendered image (one core)");
  r->add_option("--sequence", render->sequence, "Trajectory to render along")->capture_default_str();
  r->add_option("--frames", render->frames, "Images to render (spread over the sequence)")->capture_default_str();
  r->add_flag("--json", render->json, "Print one JSON object");
  r->callback([render]() { run_render_bench(*render); });

  auto features = std::make_shared<FeatureBenchOptions>();
  auto* f =
      bench->add_subcommand("features", "ORB extraction, stereo matching, BoW transform and database query times");
  f->add_option("--dataset", features->dataset, "EuRoC ASL stereo dataset (e.g. from orbatlas sim)")
      ->required()
      ->check(CLI::ExistingDirectory);
  f->add_option("--config", features->config, "Settings (default: config/euroc/stereo.yaml)");
  f->add_option("--vocabulary", features->vocabulary, "Vocabulary file (default: the shipped one)");
  f->add_option("--frames", features->frames, "Stereo frames to time (spread over the dataset)")->capture_default_str();
  f->add_option("--database-keyframes", features->database_keyframes, "Keyframes in the queried database")
      ->capture_default_str();
  f->add_flag("--json", features->json, "Print one JSON object");
  f->callback([features]() { run_feature_bench(*features); });

  auto store = std::make_shared<AtlasStoreBenchOptions>();
  auto* s = bench->add_subcommand("atlas-store", "Atlas database size, full save / load and checkpoint times");
  s->add_option("--keyframes", store->keyframes, "Keyframes of the synthetic atlas")->capture_default_str();
  s->add_option("--keypoints", store->keypoints, "ORB keypoints per keyframe")->capture_default_str();
  s->add_option("--points-per-keyframe", store->points_per_keyframe, "New map points per keyframe")
      ->capture_default_str();
  s->add_option("--vocabulary", store->vocabulary, "Vocabulary file (default: the shipped one)");
  s->add_option("--database", store->database, "Keep the database at this path (default: a removed temporary file)");
  s->add_option("--from-atlas", store->from_atlas,
                "Measure the atlas stored here (a file or postgresql:// URI) instead of a synthetic one: "
                "load it, save it into --database, load that back");
  s->add_flag("--json", store->json, "Print one JSON object");
  s->callback([store]() { run_atlas_store_bench(*store); });

  auto stereo = std::make_shared<StereoBenchOptions>();
  auto* st =
      bench->add_subcommand("stereo", "Stereo depth against exact rendered depth: disparity bias and spread by depth");
  st->add_option("--dataset", stereo->dataset,
                 "A stereo dataset rendered with `orbatlas sim --depth --depth-noise 0` (exact depth of cam0)")
      ->required()
      ->check(CLI::ExistingDirectory);
  st->add_option("--config", stereo->config, "Settings (default: config/euroc/stereo.yaml)");
  st->add_option("--frames", stereo->frames, "Stereo frames to measure (spread over the dataset)")
      ->capture_default_str();
  st->add_option("--depth-map-factor", stereo->depth_map_factor, "Depth image value per metre")->capture_default_str();
  st->add_flag("--json", stereo->json, "Print one JSON object");
  st->callback([stereo]() { run_stereo_bench(*stereo); });

  auto alignment = std::make_shared<AlignmentBenchOptions>();
  auto* a =
      bench->add_subcommand("alignment", "Horn's absolute orientation against Eigen::umeyama (microseconds, errors)");
  a->add_option("--problems", alignment->problems, "Random problems per size")
      ->capture_default_str()
      ->check(CLI::Range(1, 1000000));
  a->add_flag("--json", alignment->json, "Print one JSON object");
  a->callback([alignment]() { run_alignment_bench(*alignment); });

  auto place = std::make_shared<PlaceBenchOptions>();
  auto* p = bench->add_subcommand(
      "place", "Place recognition and relocalisation recall of another recording's frames against a map");
  p->add_option("--map", place->map, "EuRoC ASL stereo dataset the map is built from (stereo SLAM)")
      ->required()
      ->check(CLI::ExistingDirectory);
  p->add_option("--queries", place->queries,
                "EuRoC ASL stereo dataset whose frames are queried (ground truth in the same world)")
      ->required()
      ->check(CLI::ExistingDirectory);
  p->add_option("--config", place->config, "Settings (default: config/euroc/stereo.yaml)");
  p->add_option("--vocabulary", place->vocabulary, "Vocabulary file (default: the shipped one)");
  p->add_option("--every", place->every, "Query every n-th frame")->capture_default_str();
  p->add_option("--revisit-m", place->revisit_m, "A query is a revisit within this distance of a keyframe [m]")
      ->capture_default_str();
  p->add_option("--revisit-deg", place->revisit_deg, "... and this angle between the optical axes [deg]")
      ->capture_default_str();
  p->add_flag("--json", place->json, "Print one JSON object");
  p->add_flag("!--no-progress", place->show_progress, "Do not print progress");
  p->callback([place]() { run_place_bench(*place); });
}

}  // namespace orbatlas::cli
