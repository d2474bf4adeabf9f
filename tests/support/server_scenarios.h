#pragma once
// What the server's end-to-end tests share: another flight through a mapped
// place, the ground truth in a map's frame, waiting for the merging worker,
// a single camera's trajectory scored, a pose by its time.
#include <chrono>
#include <filesystem>
#include <optional>
#include <thread>

#include <nlohmann/json.hpp>

#include "client/api/server_client.h"
#include "core/eval/evaluate.h"
#include "core/geometry/trajectory.h"
#include "core/io/euroc_types.h"
#include "tests/support/slam_test_clip.h"

namespace orbatlas::test {

// Another flight through the place MH_01 maps at 40-50 s: MH_02 at 41-44 s
// passes 0.3 to 0.9 m from it, looking the same way within 25 deg; no pose
// that built the map is re-rendered.
inline std::filesystem::path another_flight() { return simulated_clip("MH_02", 41.0, 3.0); }

// The ground truth of `dataset` at t_ns in the frame of a map whose origin is
// the body at `origin_t_ns` of `origin_dataset` (all Machine Hall sequences
// share one world frame).
inline Pose3 truth_in_map(const std::filesystem::path& dataset, TimestampNs t_ns,
                          const std::filesystem::path& origin_dataset, TimestampNs origin_t_ns) {
  const auto at = [](const std::filesystem::path& d, TimestampNs t) {
    Trajectory gt;
    for (const auto& s : stereo_dataset(d).ground_truth) gt.push_back({s.t_ns, s.T_w_b});
    const auto pose = pose_at(gt, t, 50'000'000);
    EXPECT_TRUE(pose.has_value()) << d << " has no ground truth at " << t;
    return pose.value_or(Pose3());
  };
  return at(origin_dataset, origin_t_ns).inverse() * at(dataset, t_ns);
}

inline nlohmann::json wait_for_merges(ServerClient& client) {
  for (int i = 0; i < 1200; ++i) {
    const auto merges = client.get_json("/v1/merges");
    if (merges["pending"].get<std::size_t>() == 0) return merges;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return client.get_json("/v1/merges");
}

// A single camera's trajectory (the left camera's poses) against the
// dataset's ground truth.
inline EvalResult left_camera_eval(const EurocDataset& dataset, const Trajectory& trajectory, AlignMode align) {
  EvalOptions eval;
  eval.align = align;
  eval.estimate_T_b_x = dataset.cameras[0].calibration.T_b_c;
  return evaluate_trajectory(trajectory, from_ground_truth_states(dataset.ground_truth), eval);
}

inline std::optional<Pose3> pose_at_time(const Trajectory& t, TimestampNs t_ns) {
  for (const auto& p : t)
    if (p.t_ns == t_ns) return p.pose;
  return std::nullopt;
}

}  // namespace orbatlas::test
