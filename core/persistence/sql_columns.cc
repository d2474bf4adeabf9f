#include "core/persistence/sql_columns.h"

#include <limits>

#include "core/common/error.h"

namespace orbatlas {

std::int64_t sql_id(std::uint64_t id) {
  ORBATLAS_CHECK(id <= static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max()),
                 "id " << id << " does not fit a signed 64-bit database integer");
  return static_cast<std::int64_t>(id);
}

std::uint64_t id_column(const SqlStatement& row, int column) {
  const std::int64_t value = row.int64(column);
  ORBATLAS_DATA_CHECK(value >= 0, "negative stored id " << value);
  return static_cast<std::uint64_t>(value);
}

void bind_pose(SqlStatement& statement, int first_index, const Pose3& pose) {
  const Eigen::Quaterniond& q = pose.q;
  const double values[7] = {q.w(), q.x(), q.y(), q.z(), pose.t.x(), pose.t.y(), pose.t.z()};
  for (int i = 0; i < 7; ++i) statement.bind_real(first_index + i, values[i]);
}

Pose3 pose_columns(const SqlStatement& row, int first_column) {
  Pose3 pose;  // fields set directly: the Pose3 constructor would renormalise
  pose.q = Eigen::Quaterniond(row.real(first_column), row.real(first_column + 1), row.real(first_column + 2),
                              row.real(first_column + 3));
  pose.t = Eigen::Vector3d(row.real(first_column + 4), row.real(first_column + 5), row.real(first_column + 6));
  return pose;
}

}  // namespace orbatlas
