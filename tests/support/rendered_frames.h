#pragma once
// A rendered Machine Hall frame for feature tests: EuRoC cam0 on MH_01,
// `fraction` of the way through the sequence, in the default hall with coarse
// textures (texel 1 cm) so that building it is quick.
#include <opencv2/core/mat.hpp>

#include "core/camera/camera_factory.h"
#include "core/sim/euroc_sequences.h"
#include "core/sim/machine_hall.h"
#include "core/sim/renderer.h"
#include "core/sim/trajectory_spline.h"
#include "tests/support/sim_test_helpers.h"

namespace orbatlas::test {

inline cv::Mat render_machine_hall_frame(double fraction) {
  sim::MachineHallOptions hall;
  hall.texel_size_m = 0.01;
  const sim::World world = sim::build_machine_hall(sim::load_machine_hall_trajectories(), hall);
  const CameraCalibration cal = euroc_cam0();
  const auto camera = make_camera(cal);
  const sim::TrajectorySpline spline(sim::load_ground_truth(sim::find_sequence("MH_01")));
  const TimestampNs t =
      spline.start_ns() + static_cast<TimestampNs>(fraction * static_cast<double>(spline.end_ns() - spline.start_ns()));
  sim::Renderer renderer(world, *camera);
  cv::Mat image;
  renderer.render(spline.pose(t) * cal.T_b_c, image, 7);
  return image;
}

}  // namespace orbatlas::test
