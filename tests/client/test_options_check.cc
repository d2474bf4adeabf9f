// Every options struct checks itself: its defaults pass, and a
// value the code cannot work with throws Error naming the field. One line per
// refused value; parents are shown to check their parts.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <string>

#include "client/benchmarks.h"
#include "core/common/error.h"
#include "core/estimators/pnp_ransac.h"
#include "core/estimators/sim3_solver.h"
#include "core/eval/association.h"
#include "core/eval/evaluate.h"
#include "core/features/matching.h"
#include "core/features/orb_extractor.h"
#include "core/features/stereo_rectified.h"
#include "core/features/stereo_triangulated.h"
#include "core/loop/loop_closer.h"
#include "core/loop/loop_correction.h"
#include "core/loop/map_merge.h"
#include "core/loop/place_recognizer.h"
#include "core/map/redundancy.h"
#include "core/mapping/keyframe_culling.h"
#include "core/mapping/local_mapper.h"
#include "core/optimization/essential_graph.h"
#include "core/optimization/global_bundle_adjustment.h"
#include "core/optimization/local_bundle_adjustment.h"
#include "core/optimization/pose_optimizer.h"
#include "core/optimization/sim3_refinement.h"
#include "core/persistence/atlas_checkpointer.h"
#include "core/relocalization/relocalizer.h"
#include "core/server/atlas_service.h"
#include "core/server/map_merge_worker.h"
#include "core/sim/imu_synthesizer.h"
#include "core/sim/look.h"
#include "core/sim/machine_hall.h"
#include "core/sim/renderer.h"
#include "core/sim/sequence_simulator.h"
#include "core/sim/trajectory_spline.h"
#include "core/pipeline/dataset_runner.h"
#include "core/slam/mono_localizer.h"
#include "core/slam/slam_system.h"
#include "core/tracking/keyframe_points.h"
#include "core/tracking/tracker.h"
#include "core/vocabulary/kmedians.h"
#include "core/vocabulary/vocabulary.h"

namespace orbatlas {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// A default T with `change` applied must be refused with a message naming `field`.
template <class T>
void refused(const std::string& field, const std::function<void(T&)>& change) {
  T options;
  change(options);
  try {
    options.check();
    ADD_FAILURE() << field << ": accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << field << ": " << e.what();
  }
}

TEST(OptionsCheck, TrackingAndSessions) {
  EXPECT_NO_THROW(TrackerOptions{}.check());
  refused<TrackerOptions>("min_init_stereo_points", [](auto& o) { o.min_init_stereo_points = 0; });
  refused<TrackerOptions>("th_depth_m", [](auto& o) { o.th_depth_m = kNaN; });
  refused<TrackerOptions>("max_frames_between_keyframes", [](auto& o) { o.max_frames_between_keyframes = 0; });
  refused<TrackerOptions>("min_inliers", [](auto& o) { o.min_inliers = -1; });
  refused<TrackerOptions>("min_inliers_after_recovery", [](auto& o) { o.min_inliers_after_recovery = -1; });
  refused<TrackerOptions>("recently_lost_s", [](auto& o) { o.recently_lost_s = -1.0; });
  refused<TrackerOptions>("new_map_after_failed_relocalizations",
                          [](auto& o) { o.new_map_after_failed_relocalizations = -1; });
  refused<TrackerOptions>("max_local_keyframes", [](auto& o) { o.max_local_keyframes = -1; });
  refused<TrackerOptions>("min_keyframes_to_keep_map", [](auto& o) { o.min_keyframes_to_keep_map = -1; });
  EXPECT_NO_THROW(KeyframePointsOptions{}.check());
  refused<KeyframePointsOptions>("th_depth_m", [](auto& o) { o.th_depth_m = -1.0; });
  refused<KeyframePointsOptions>("min_points", [](auto& o) { o.min_points = -1; });

  EXPECT_NO_THROW(SlamSystemOptions{}.check());
  refused<SlamSystemOptions>("relocalization", [](auto& o) {
    o.tracker.localization_only = true;
    o.relocalization = false;
  });
  refused<SlamSystemOptions>("min_inliers", [](auto& o) { o.tracker.min_inliers = -1; });
  refused<SlamSystemOptions>("queue_capacity", [](auto& o) { o.mapper.queue_capacity = 0; });
  refused<SlamSystemOptions>("bow_ratio", [](auto& o) { o.loop.recognition.bow_ratio = 1.5f; });
  refused<SlamSystemOptions>("num_threads", [](auto& o) { o.final_ba.num_threads = 0; });
  refused<SlamSystemOptions>("shared_map_finish_wait_s", [](auto& o) { o.shared_map_finish_wait_s = -1.0; });
  EXPECT_NO_THROW(MonoLocalizerOptions{}.check());
  refused<MonoLocalizerOptions>("recently_lost_s", [](auto& o) { o.tracker.recently_lost_s = kNaN; });
  EXPECT_NO_THROW(DatasetRunOptions{}.check());
  refused<DatasetRunOptions>("start_s", [](auto& o) { o.start_s = -1.0; });
  refused<DatasetRunOptions>("duration_s", [](auto& o) { o.duration_s = 0.0; });
  refused<DatasetRunOptions>("localize_only", [](auto& o) { o.localize_only = true; });
  refused<DatasetRunOptions>("max_frames_between_keyframes",
                             [](auto& o) { o.slam.tracker.max_frames_between_keyframes = -3; });
  refused<DatasetRunOptions>("every_seconds", [](auto& o) { o.checkpoints.every_seconds = kNaN; });
  EXPECT_NO_THROW(CheckpointOptions{}.check());
  refused<CheckpointOptions>("every_seconds", [](auto& o) { o.every_seconds = kNaN; });
}

TEST(OptionsCheck, MappingAndOptimisation) {
  EXPECT_NO_THROW(LocalMapperOptions{}.check());
  refused<LocalMapperOptions>("queue_capacity", [](auto& o) { o.queue_capacity = 0; });
  refused<LocalMapperOptions>("fusion_radius", [](auto& o) { o.fusion_radius = -1.0f; });
  refused<LocalMapperOptions>("redundant_fraction", [](auto& o) { o.culling.redundancy.redundant_fraction = 1.5; });
  refused<LocalMapperOptions>("second_iterations", [](auto& o) { o.bundle_adjustment.second_iterations = -1; });
  EXPECT_NO_THROW(KeyframeCullingOptions{}.check());
  refused<KeyframeCullingOptions>("scheme", [](auto& o) { o.scheme = static_cast<CullingScheme>(7); });
  EXPECT_NO_THROW(RedundancyOptions{}.check());
  refused<RedundancyOptions>("redundant_fraction", [](auto& o) { o.redundant_fraction = kNaN; });

  EXPECT_NO_THROW(LocalBundleAdjustmentOptions{}.check());
  refused<LocalBundleAdjustmentOptions>("first_iterations", [](auto& o) { o.first_iterations = -1; });
  refused<LocalBundleAdjustmentOptions>("chi2_mono", [](auto& o) { o.chi2_mono = 0.0; });
  refused<LocalBundleAdjustmentOptions>("chi2_stereo", [](auto& o) { o.chi2_stereo = kNaN; });
  refused<LocalBundleAdjustmentOptions>("huber_mono", [](auto& o) { o.huber_mono = -1.0; });
  refused<LocalBundleAdjustmentOptions>("huber_stereo", [](auto& o) { o.huber_stereo = 0.0; });
  refused<LocalBundleAdjustmentOptions>("level_sigma2", [](auto& o) { o.level_sigma2.clear(); });
  refused<LocalBundleAdjustmentOptions>("level_sigma2[2]", [](auto& o) { o.level_sigma2[2] = 0.0; });
  refused<LocalBundleAdjustmentOptions>("num_threads", [](auto& o) { o.num_threads = 0; });
  EXPECT_NO_THROW(GlobalBundleAdjustmentOptions{}.check());
  refused<GlobalBundleAdjustmentOptions>("iterations", [](auto& o) { o.iterations = -1; });
  refused<GlobalBundleAdjustmentOptions>("huber_stereo", [](auto& o) { o.huber_stereo = kNaN; });
  refused<GlobalBundleAdjustmentOptions>("level_sigma2", [](auto& o) { o.level_sigma2 = {1.0, -2.0}; });
  refused<GlobalBundleAdjustmentOptions>("num_threads", [](auto& o) { o.num_threads = -1; });
  EXPECT_NO_THROW(PoseOptimizerOptions{}.check());
  refused<PoseOptimizerOptions>("rounds", [](auto& o) { o.rounds = -1; });
  refused<PoseOptimizerOptions>("iterations_per_round", [](auto& o) { o.iterations_per_round = -1; });
  refused<PoseOptimizerOptions>("chi2_mono", [](auto& o) { o.chi2_mono = kNaN; });
  refused<PoseOptimizerOptions>("huber_stereo", [](auto& o) { o.huber_stereo = 0.0; });
  refused<PoseOptimizerOptions>("min_round_inliers", [](auto& o) { o.min_round_inliers = -1; });
  EXPECT_NO_THROW(EssentialGraphOptions{}.check());
  refused<EssentialGraphOptions>("max_iterations", [](auto& o) { o.max_iterations = -1; });
  refused<EssentialGraphOptions>("num_threads", [](auto& o) { o.num_threads = 0; });
  EXPECT_NO_THROW(Sim3RefinementOptions{}.check());
  refused<Sim3RefinementOptions>("chi2_threshold", [](auto& o) { o.chi2_threshold = 0.0; });
  refused<Sim3RefinementOptions>("second_iterations_clean", [](auto& o) { o.second_iterations_clean = -1; });
  refused<Sim3RefinementOptions>("min_inliers", [](auto& o) { o.min_inliers = -1; });
  EXPECT_NO_THROW(Sim3SolverOptions{}.check());
  refused<Sim3SolverOptions>("probability", [](auto& o) { o.probability = 1.0; });
  refused<Sim3SolverOptions>("max_iterations", [](auto& o) { o.max_iterations = -1; });
  refused<Sim3SolverOptions>("chi2", [](auto& o) { o.chi2 = kNaN; });
}

TEST(OptionsCheck, PlacesLoopsAndMerging) {
  EXPECT_NO_THROW(PnpRansacOptions{}.check());
  refused<PnpRansacOptions>("max_iterations", [](auto& o) { o.max_iterations = 0; });
  refused<PnpRansacOptions>("max_angle_rad", [](auto& o) { o.max_angle_rad = 0.0; });
  refused<PnpRansacOptions>("min_inliers", [](auto& o) { o.min_inliers = -1; });
  refused<PnpRansacOptions>("confidence", [](auto& o) { o.confidence = 1.0; });
  EXPECT_NO_THROW(RelocalizationOptions{}.check());
  refused<RelocalizationOptions>("min_bow_matches", [](auto& o) { o.min_bow_matches = -1; });
  refused<RelocalizationOptions>("bow_ratio", [](auto& o) { o.bow_ratio = -0.1f; });
  refused<RelocalizationOptions>("guided_radius", [](auto& o) { o.guided_radius = std::nanf(""); });
  refused<RelocalizationOptions>("confidence", [](auto& o) { o.pnp.confidence = kNaN; });

  EXPECT_NO_THROW(PlaceRecognitionOptions{}.check());
  refused<PlaceRecognitionOptions>("scope", [](auto& o) { o.scope = static_cast<PlaceScope>(-1); });
  refused<PlaceRecognitionOptions>("bow_ratio", [](auto& o) { o.bow_ratio = 1.01f; });
  refused<PlaceRecognitionOptions>("min_ransac_inliers", [](auto& o) { o.min_ransac_inliers = -1; });
  refused<PlaceRecognitionOptions>("first_search_th", [](auto& o) { o.first_search_th = -3.0f; });
  refused<PlaceRecognitionOptions>("second_search_th", [](auto& o) { o.second_search_th = INFINITY; });
  refused<PlaceRecognitionOptions>("min_final_matches", [](auto& o) { o.min_final_matches = -1; });
  refused<PlaceRecognitionOptions>("verify_keyframes", [](auto& o) { o.verify_keyframes = -1; });
  EXPECT_NO_THROW(LoopCorrectionOptions{}.check());
  refused<LoopCorrectionOptions>("fusion_th", [](auto& o) { o.fusion_th = std::nanf(""); });
  refused<LoopCorrectionOptions>("strong_covisibility", [](auto& o) { o.strong_covisibility = -1; });
  refused<LoopCorrectionOptions>("max_iterations", [](auto& o) { o.graph.max_iterations = -1; });
  EXPECT_NO_THROW(MapMergeOptions{}.check());
  refused<MapMergeOptions>("fusion_th", [](auto& o) { o.fusion_th = -1.0f; });
  EXPECT_NO_THROW(LoopCloserOptions{}.check());
  refused<LoopCloserOptions>("queue_capacity", [](auto& o) { o.queue_capacity = 0; });
  refused<LoopCloserOptions>("min_bow_matches", [](auto& o) { o.merge_recognition.min_bow_matches = -2; });
  refused<LoopCloserOptions>("fusion_th", [](auto& o) { o.merge.fusion_th = -1.0f; });
  refused<LoopCloserOptions>("iterations", [](auto& o) { o.global.iterations = -1; });
  refused<LoopCloserOptions>("shared_map_refinement_growth", [](auto& o) { o.shared_map_refinement_growth = -0.5; });
  refused<LoopCloserOptions>("stream_end_refinement_growth", [](auto& o) { o.stream_end_refinement_growth = -0.1; });
  EXPECT_NO_THROW(MapMergeWorkerOptions{}.check());
  refused<MapMergeWorkerOptions>("queue_capacity", [](auto& o) { o.queue_capacity = 0; });
  refused<MapMergeWorkerOptions>("verify_matches", [](auto& o) { o.recognition.verify_matches = -1; });
  refused<MapMergeWorkerOptions>("num_threads", [](auto& o) { o.global.num_threads = 0; });
  refused<AtlasServiceOptions>("finish_refinement_wait_s", [](auto& o) {
    o.db = "atlas.db";
    o.finish_refinement_wait_s = -1.0;
  });
}

TEST(OptionsCheck, FeaturesAndVocabulary) {
  EXPECT_NO_THROW(OrbExtractorOptions{}.check());
  refused<OrbExtractorOptions>("n_levels", [](auto& o) { o.n_levels = 0; });
  EXPECT_NO_THROW(BruteForceMatchOptions{}.check());
  refused<BruteForceMatchOptions>("max_distance", [](auto& o) { o.max_distance = -1; });
  refused<BruteForceMatchOptions>("ratio", [](auto& o) { o.ratio = 1.2f; });
  EXPECT_NO_THROW(GuidedMatchOptions{}.check());
  refused<GuidedMatchOptions>("radius_px", [](auto& o) { o.radius_px = -1.0f; });
  refused<GuidedMatchOptions>("level_scale", [](auto& o) { o.level_scale = 0.0f; });
  refused<GuidedMatchOptions>("level_window", [](auto& o) { o.level_window = -2; });
  refused<GuidedMatchOptions>("ratio", [](auto& o) { o.ratio = std::nanf(""); });
  EXPECT_NO_THROW(StereoMatchOptions{}.check());
  refused<StereoMatchOptions>("max_hamming", [](auto& o) { o.max_hamming = -1; });
  refused<StereoMatchOptions>("sad_half_window", [](auto& o) { o.sad_half_window = 0; });
  refused<StereoMatchOptions>("sad_search", [](auto& o) { o.sad_search = -1; });
  refused<StereoMatchOptions>("min_depth_baselines", [](auto& o) { o.min_depth_baselines = 0.0; });
  refused<StereoMatchOptions>("outlier_factor", [](auto& o) { o.outlier_factor = kNaN; });
  EXPECT_NO_THROW(TriangulatedStereoOptions{}.check());
  refused<TriangulatedStereoOptions>("ratio", [](auto& o) { o.ratio = 2.0; });
  refused<TriangulatedStereoOptions>("max_reprojection_sigma2", [](auto& o) { o.max_reprojection_sigma2 = 0.0; });
  refused<TriangulatedStereoOptions>("min_parallax_deg", [](auto& o) { o.min_parallax_deg = -1.0; });
  refused<TriangulatedStereoOptions>("sad_half_window", [](auto& o) { o.sad_half_window = 0; });
  EXPECT_NO_THROW(VocabularyTrainingOptions{}.check());
  refused<VocabularyTrainingOptions>("levels", [](auto& o) { o.levels = 0; });
  using vocabulary_detail::KmediansOptions;
  EXPECT_NO_THROW(KmediansOptions{}.check());
  refused<KmediansOptions>("k", [](auto& o) { o.k = 1; });
  refused<KmediansOptions>("iterations", [](auto& o) { o.iterations = 0; });
  refused<KmediansOptions>("threads", [](auto& o) { o.threads = -1; });
}

TEST(OptionsCheck, SimulatorEvaluationAndBenchmarks) {
  using namespace sim;
  EXPECT_NO_THROW(RenderOptions{}.check());
  refused<RenderOptions>("noise_sigma", [](auto& o) { o.noise_sigma = -1.0; });
  refused<RenderOptions>("near_m", [](auto& o) { o.near_m = 0.0; });
  refused<RenderOptions>("max_canvas_scale", [](auto& o) { o.max_canvas_scale = kNaN; });
  refused<RenderOptions>("canvas_focal_scale", [](auto& o) { o.canvas_focal_scale = 5.0; });
  EXPECT_NO_THROW(SplineOptions{}.check());
  refused<SplineOptions>("knot_spacing_s", [](auto& o) { o.knot_spacing_s = 0.0; });
  refused<SplineOptions>("smoothing_sigma_s", [](auto& o) { o.smoothing_sigma_s = kNaN; });
  EXPECT_NO_THROW(RealCameraOptions{}.check());
  refused<RealCameraOptions>("illumination", [](auto& o) { o.illumination = 0.0; });
  refused<RealCameraOptions>("max_exposure_ms", [](auto& o) { o.max_exposure_ms = 0.1; });
  refused<RealCameraOptions>("max_gain", [](auto& o) { o.max_gain = 0.5; });
  refused<RealCameraOptions>("drift_period_s", [](auto& o) { o.drift_period_s = 0.0; });
  refused<RealCameraOptions>("vignetting", [](auto& o) { o.vignetting = 1.5; });
  refused<RealCameraOptions>("shot_noise", [](auto& o) { o.shot_noise = -0.1; });
  refused<RealCameraOptions>("max_blur_subframes", [](auto& o) { o.max_blur_subframes = 0; });
  refused<RealCameraOptions>("blur_px_per_subframe", [](auto& o) { o.blur_px_per_subframe = 0.0; });
  EXPECT_NO_THROW(RealLookOptions{}.check());
  refused<RealLookOptions>("calibration_error", [](auto& o) { o.calibration_error = -1.0; });
  refused<RealLookOptions>("read_noise", [](auto& o) { o.camera.read_noise = -1.0; });
  EXPECT_NO_THROW(ImuSynthesisOptions{}.check());
  refused<ImuSynthesisOptions>("rate_hz", [](auto& o) { o.calibration.rate_hz = 0.0; });
  refused<ImuSynthesisOptions>("gyro_noise_density", [](auto& o) { o.calibration.gyro_noise_density = -1.0; });
  refused<ImuSynthesisOptions>("accel_bias_sigma", [](auto& o) { o.errors.accel_bias_sigma.x() = kNaN; });
  refused<ImuSynthesisOptions>("vibration", [](auto& o) { o.errors.vibration = -0.1; });
  refused<ImuSynthesisOptions>("scale_error", [](auto& o) { o.errors.scale_error = 0.5; });
  refused<ImuSynthesisOptions>("time_offset_s", [](auto& o) { o.errors.time_offset_s = kNaN; });
  refused<ImuSynthesisOptions>("extrinsic_rotation_deg", [](auto& o) { o.errors.extrinsic_rotation_deg = -1.0; });
  EXPECT_NO_THROW(realistic_imu_errors().check());
  EXPECT_NO_THROW(MachineHallOptions{}.check());
  refused<MachineHallOptions>("clearance_m", [](auto& o) { o.clearance_m = -1.0; });
  refused<MachineHallOptions>("machine_count", [](auto& o) { o.machine_count = -1; });
  refused<MachineHallOptions>("texel_size_m", [](auto& o) { o.texel_size_m = 0.0; });
  SimulationOptions simulation;
  simulation.out_dir = "/tmp/orbatlas-never-written";
  EXPECT_NO_THROW(simulation.check());
  const auto sim_refused = [&](const std::string& field, const std::function<void(SimulationOptions&)>& change) {
    refused<SimulationOptions>(field, [&](auto& o) {
      o = simulation;
      change(o);
    });
  };
  sim_refused("out_dir", [](auto& o) { o.out_dir.clear(); });
  sim_refused("start_s", [](auto& o) { o.start_s = -1.0; });
  sim_refused("duration_s", [](auto& o) { o.duration_s = kNaN; });
  sim_refused("every", [](auto& o) { o.every = 0; });
  sim_refused("noise_sigma", [](auto& o) { o.noise_sigma = 60.0; });
  sim_refused("look", [](auto& o) { o.look = static_cast<Look>(5); });
  sim_refused("illumination", [](auto& o) {
    o.real = RealLookOptions{};
    o.real->camera.illumination = -1.0;
  });
  sim_refused("threads", [](auto& o) { o.threads = -1; });

  EXPECT_NO_THROW(AssociationOptions{}.check());
  refused<AssociationOptions>("max_gap_ns", [](auto& o) { o.max_gap_ns = -1; });
  refused<AssociationOptions>("exact_tol_ns", [](auto& o) { o.exact_tol_ns = -1; });
  EXPECT_NO_THROW(EvalOptions{}.check());
  refused<EvalOptions>("align", [](auto& o) { o.align = static_cast<AlignMode>(9); });
  refused<EvalOptions>("rpe_delta_ns", [](auto& o) { o.rpe_delta_ns = 0; });
  refused<EvalOptions>("max_gap_ns", [](auto& o) { o.association.max_gap_ns = -5; });

  using namespace cli;
  EXPECT_NO_THROW(RenderBenchOptions{}.check());
  refused<RenderBenchOptions>("frames", [](auto& o) { o.frames = 0; });
  EXPECT_NO_THROW(FeatureBenchOptions{}.check());
  refused<FeatureBenchOptions>("frames", [](auto& o) { o.frames = -1; });
  refused<FeatureBenchOptions>("database_keyframes", [](auto& o) { o.database_keyframes = 0; });
  EXPECT_NO_THROW(AtlasStoreBenchOptions{}.check());
  refused<AtlasStoreBenchOptions>("keyframes", [](auto& o) { o.keyframes = 1; });
  refused<AtlasStoreBenchOptions>("keypoints", [](auto& o) { o.keypoints = 0; });
  refused<AtlasStoreBenchOptions>("points_per_keyframe", [](auto& o) { o.points_per_keyframe = -1; });
  EXPECT_NO_THROW(AlignmentBenchOptions{}.check());
  refused<AlignmentBenchOptions>("problems", [](auto& o) { o.problems = 0; });
  EXPECT_NO_THROW(PlaceBenchOptions{}.check());
  refused<PlaceBenchOptions>("every", [](auto& o) { o.every = 0; });
  refused<PlaceBenchOptions>("revisit_m", [](auto& o) { o.revisit_m = 0.0; });
  refused<PlaceBenchOptions>("revisit_deg", [](auto& o) { o.revisit_deg = kNaN; });
}

// Functions that take options refuse bad ones before doing anything.
TEST(OptionsCheck, ConsumersCheckAtEntry) {
  EssentialGraphOptions graph;
  graph.num_threads = 0;
  EXPECT_THROW(optimize_essential_graph({}, {}, graph), Error);
  AssociationOptions association;
  association.exact_tol_ns = -1;
  EXPECT_THROW(associate({}, {}, association), Error);
  DatasetRunOptions run;
  run.start_s = kNaN;
  EXPECT_THROW(run_dataset(run), Error);
  sim::SimulationOptions simulation;
  simulation.out_dir = "/tmp/orbatlas-never-written";
  simulation.every = 0;
  EXPECT_THROW(sim::simulate_sequence(simulation), Error);
}

}  // namespace
}  // namespace orbatlas
