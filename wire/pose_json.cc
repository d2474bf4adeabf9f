#include "wire/pose_json.h"

#include "core/common/error.h"

namespace orbatlas {

nlohmann::json pose_to_json(const Pose3& pose) {
  return {{"t", {pose.t.x(), pose.t.y(), pose.t.z()}}, {"q", {pose.q.x(), pose.q.y(), pose.q.z(), pose.q.w()}}};
}

Pose3 pose_from_json(const nlohmann::json& j) {
  const auto t = j.at("t").get<std::vector<double>>();
  const auto q = j.at("q").get<std::vector<double>>();
  ORBATLAS_CHECK(t.size() == 3 && q.size() == 4, "a pose is {\"t\": [x, y, z], \"q\": [qx, qy, qz, qw]}");
  Pose3 pose;
  pose.t = Eigen::Vector3d(t[0], t[1], t[2]);
  pose.q = Eigen::Quaterniond(q[3], q[0], q[1], q[2]).normalized();
  return pose;
}

}  // namespace orbatlas
