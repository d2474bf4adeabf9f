// Place recognition on simulated revisits: MH_01 keyframes form the database,
// MH_02 frames that pass the same spots are the queries. The shipped vocabulary
// was trained on other scene seeds, so the hall here is new to it.
#include <gtest/gtest.h>

#include <filesystem>

#include "core/camera/camera_factory.h"
#include "core/features/orb_extractor.h"
#include "core/sim/euroc_sequences.h"
#include "core/sim/machine_hall.h"
#include "core/sim/renderer.h"
#include "core/sim/trajectory_spline.h"
#include "core/vocabulary/default_vocabulary.h"
#include "core/vocabulary/keyframe_database.h"
#include "core/vocabulary/vocabulary.h"
#include "tests/support/sim_test_helpers.h"

namespace orbatlas {
namespace {

struct View {
  Pose3 T_w_c;
  BowVector bow;
};

double axis_angle_deg(const Pose3& a, const Pose3& b) {
  const double c = a.rotation().col(2).dot(b.rotation().col(2));
  return std::acos(std::clamp(c, -1.0, 1.0)) * 180.0 / M_PI;
}

TEST(PlaceRecognition, TruePlaceInTopThreeOnMachineHallRevisits) {
  ASSERT_TRUE(std::filesystem::exists(default_vocabulary_path())) << default_vocabulary_path();
  const Vocabulary vocabulary = Vocabulary::load(default_vocabulary_path());
  const CameraCalibration cal = test::euroc_cam0();
  const auto camera = make_camera(cal);
  sim::MachineHallOptions hall;
  hall.seed = 1;  // the default hall; the vocabulary never saw it
  const sim::World world = sim::build_machine_hall(sim::load_machine_hall_trajectories(), hall);
  sim::Renderer renderer(world, *camera);
  OrbExtractorOptions eo;
  eo.n_features = 1000;
  OrbExtractor extractor(eo);
  cv::Mat image;
  auto view_at = [&](const sim::TrajectorySpline& spline, TimestampNs t, std::uint64_t seed) {
    View v;
    v.T_w_c = spline.pose(t) * cal.T_b_c;
    renderer.render(v.T_w_c, image, seed);
    const ImageFeatures f = extractor.extract(image);
    vocabulary.transform(f.descriptors, &v.bow, nullptr);
    return v;
  };

  const sim::TrajectorySpline mh01(sim::load_ground_truth(sim::find_sequence("MH_01")));
  const sim::TrajectorySpline mh02(sim::load_ground_truth(sim::find_sequence("MH_02")));
  std::vector<View> keyframes;
  KeyframeDatabase database;
  for (TimestampNs t = mh01.start_ns(); t <= mh01.end_ns(); t += kNsPerSecond / 2) {
    keyframes.push_back(view_at(mh01, t, keyframes.size()));
    database.add(keyframes.size() - 1, keyframes.back().bow);
  }

  int queries = 0, found = 0;
  for (TimestampNs t = mh02.start_ns(); t <= mh02.end_ns(); t += 2 * kNsPerSecond) {
    const Pose3 T_w_c = mh02.pose(t) * cal.T_b_c;
    // A revisit: some keyframe looks at the same spot from nearly the same pose.
    const bool revisit = std::any_of(keyframes.begin(), keyframes.end(), [&](const View& k) {
      return (k.T_w_c.t - T_w_c.t).norm() < 0.75 && axis_angle_deg(k.T_w_c, T_w_c) < 20.0;
    });
    if (!revisit) continue;
    const View q = view_at(mh02, t, 100000 + queries);
    ++queries;
    const auto results = database.query(q.bow, 3);
    const bool hit = std::any_of(results.begin(), results.end(), [&](const DatabaseMatch& m) {
      const View& k = keyframes[m.keyframe];
      return (k.T_w_c.t - T_w_c.t).norm() < 1.5 && axis_angle_deg(k.T_w_c, T_w_c) < 35.0;
    });
    found += hit ? 1 : 0;
  }
  ASSERT_GE(queries, 20) << "too few revisits to measure";
  EXPECT_GE(found, static_cast<int>(std::ceil(0.9 * queries)));
}

}  // namespace
}  // namespace orbatlas
